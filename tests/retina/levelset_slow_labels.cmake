# Included by ctest after the discovered gtest tests: the full-size level-set check renders a
# 145 x 384 x 496 phantom (seconds in Release, about a minute under the sanitizers).
set_tests_properties(LevelSetOverhangFullSize.FollowsTheIlmUnderTheRimLip PROPERTIES LABELS slow)
