# Included by ctest after the discovered gtest tests: the level-set tests render ONH phantoms
# (73 x 192 x 496, and 145 x 384 x 496 for the full-size check) and run the whole ILM pipeline:
# seconds each in Release, minutes under the sanitizers. Label them slow (they still run).
foreach(_t LevelSetOverhangFullSize.FollowsTheIlmUnderTheRimLip LevelSetPhantom.Cupped
           LevelSetPhantom.Swollen LevelSetPhantom.Overhang
           LevelSetPhantom.BandMeansMoveTheSurfaceOntoTheEdge LevelSet.MissingDeviceIlmIsFilledAndClipped)
  set_tests_properties(${_t} PROPERTIES LABELS slow)
endforeach()
