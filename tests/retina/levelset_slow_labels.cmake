# Included by ctest after the discovered gtest tests: the level-set tests render ONH phantoms
# (73 x 192 x 496, and 145 x 384 x 496 for the full-size check) and run the whole ILM pipeline:
# seconds each in Release, minutes under the sanitizers. Label them slow (they still run).
set_tests_properties(LevelSetOverhangFullSize.FollowsTheIlmUnderTheRimLip PROPERTIES LABELS slow)
foreach(_s cupped swollen overhang)
  set_tests_properties(Shapes/LevelSetPhantom.OneSheetNearTheTruthAndRofiRemovesTheStaircase/${_s}
                       PROPERTIES LABELS slow)
endforeach()
