# Included by ctest after the discovered gtest tests: the kill-and-resume test runs a batch
# about 13 times (seconds in Release, tens of seconds under the sanitizers): label it slow.
set_tests_properties(CohortKill.SigkillAtRandomMomentsThenRerunGivesTheUninterruptedTables
  PROPERTIES LABELS slow)
