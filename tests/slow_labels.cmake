# cmake -DOUT=FILE -DDIR=SOURCE_DIR -DSOURCES="a.cpp;b.cpp" -P slow_labels.cmake
# Writes one ctest `set_tests_properties(Suite.Name PROPERTIES LABELS slow)` per line that starts
# with SLOW_TEST(Suite, Name) in the given test sources (tests/slow_test.h): the "slow" label is
# set where the test is defined. ctest includes OUT after discovering the gtest tests.
set(_out "# Generated from the SLOW_TEST( lines of the test sources (tests/slow_labels.cmake).\n")
foreach(_src IN LISTS SOURCES)
  file(STRINGS "${DIR}/${_src}" _lines REGEX "^SLOW_TEST\\(")
  foreach(_line IN LISTS _lines)
    string(REGEX REPLACE "^SLOW_TEST\\(([A-Za-z0-9_]+), *([A-Za-z0-9_]+)\\).*" "\\1.\\2"
           _name "${_line}")
    string(APPEND _out "set_tests_properties(${_name} PROPERTIES LABELS slow)\n")
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
