# cmake -DOUT=FILE -DDIR=SOURCE_DIR -DSOURCES="a.cpp;b.cpp" -P slow_labels.cmake
# Writes one ctest `set_tests_properties(Suite.Name PROPERTIES LABELS slow)` per line that starts
# with SLOW_TEST(Suite, Name) in the given test sources, and `... LABELS external` per line that
# starts with EXTERNAL_TEST(Suite, Name), and `... LABELS "slow;accuracy"` per line that starts
# with ACCURACY_TEST(Suite, Name) (tests/slow_test.h): a label is set where the test is
# defined; a slow or accuracy test gets COST 10 (started early). ctest includes OUT after discovering the
# gtest tests.
set(_out "# Generated from the SLOW_TEST( / EXTERNAL_TEST( / ACCURACY_TEST( lines of the test sources (tests/slow_labels.cmake).\n")
foreach(_src IN LISTS SOURCES)
  foreach(_kind slow external accuracy)
    string(TOUPPER "${_kind}_TEST" _macro)
    file(STRINGS "${DIR}/${_src}" _lines REGEX "^${_macro}\\(")
    foreach(_line IN LISTS _lines)
      string(REGEX REPLACE "^${_macro}\\(([A-Za-z0-9_]+), *([A-Za-z0-9_]+)\\).*" "\\1.\\2"
             _name "${_line}")
      # COST: on a clean clone (no timings of an earlier run) ctest starts the slow tests
      # first, so that the short ones fill the other core instead of a slow one running last.
      if(_kind STREQUAL "slow")
        set(_props "LABELS slow COST 10")
      elseif(_kind STREQUAL "accuracy")
        set(_props "LABELS \"slow;accuracy\" COST 10")
      else()
        set(_props "LABELS ${_kind}")
      endif()
      string(APPEND _out "set_tests_properties(${_name} PROPERTIES ${_props})\n")
    endforeach()
  endforeach()
endforeach()
# Rewritten only when it changes, so ctest and the build see a stable file.
if(EXISTS "${OUT}")
  file(READ "${OUT}" _old)
else()
  set(_old "")
endif()
if(NOT _old STREQUAL _out)
  file(WRITE "${OUT}" "${_out}")
endif()
