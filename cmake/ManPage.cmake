# cmake -DEXE=octshape -DOUT=octshape.1 -P ManPage.cmake
# Writes the manual page that `octshape --man-page` prints (made from the --help text), at
# build time; fails the build when the executable fails. Rewritten only when it changes.
execute_process(COMMAND ${CMAKE_COMMAND} -E env ASAN_OPTIONS=detect_leaks=0 "${EXE}" --man-page
                OUTPUT_VARIABLE page RESULT_VARIABLE rc ERROR_VARIABLE err)
if(NOT rc EQUAL 0 OR page STREQUAL "")
  message(FATAL_ERROR "octshape --man-page failed (${rc}): ${err}")
endif()
file(WRITE "${OUT}.new" "${page}")
file(COPY_FILE "${OUT}.new" "${OUT}" ONLY_IF_DIFFERENT)
file(REMOVE "${OUT}.new")
