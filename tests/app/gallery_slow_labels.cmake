# Included by ctest after the discovered gtest tests: the gallery test analyses two phantoms and
# starts headless Chromium twice (~7 s alone, over 10 s on a loaded machine): label it slow.
set_tests_properties(Gallery.PageInHeadlessChromium PROPERTIES LABELS slow)
