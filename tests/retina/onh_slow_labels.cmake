# Included by ctest after the discovered gtest tests: the ONH tests on full-size phantoms
# (145 x 384 x 496, rendered with their truth) take seconds, ~10x more under the sanitizers.
foreach(_t CuppedWithDeviceIlm SwollenWithDeviceIlm OverhangWithDeviceIlmIsBlindToTheCavity
           CuppedWithLevelSetIlm SwollenWithLevelSetIlm
           OverhangLevelSetIsCloserToTheTruthThanTheDeviceGraph)
  set_tests_properties(OnhPhantomTruth.${_t} PROPERTIES LABELS slow)
endforeach()
