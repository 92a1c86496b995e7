# Included by ctest after the discovered gtest tests: the CuBe tests on full-size phantom
# volumes (up to 401 B-scans x 768 A-scans) take seconds under the sanitizers: label them slow.
foreach(_t BezierIdealSamplingFitsExactly BezierErrorsWithinSamplingBoundsAndShrinkWithBScans
           ScheibeWithinOnePercentAt193 ScheibeFlatPitsHitTheModelLimit
           SegmentationNoiseGivesRmseOfTheNoiseLevel)
  set_tests_properties(CubePhantom.${_t} PROPERTIES LABELS slow)
endforeach()
