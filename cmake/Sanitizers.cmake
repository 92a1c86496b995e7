# AddressSanitizer + UndefinedBehaviorSanitizer for the test preset: every octshape target and
# the test runner are instrumented; UB aborts instead of printing and carrying on.
add_library(octshape_sanitizers INTERFACE)
if(OCTSHAPE_SANITIZE)
  set(_san -fsanitize=address,undefined -fno-sanitize-recover=all -fno-omit-frame-pointer)
  target_compile_options(octshape_sanitizers INTERFACE ${_san})
  target_link_options(octshape_sanitizers INTERFACE ${_san})
endif()
# libFuzzer preset (clang only): every first-party target gets ASan + UBSan and the fuzzer's
# coverage instrumentation (fuzzer-no-link); the fuzz executables add -fsanitize=fuzzer.
if(OCTSHAPE_FUZZ)
  if(NOT CMAKE_CXX_COMPILER_ID STREQUAL "Clang")
    message(FATAL_ERROR "OCTSHAPE_FUZZ needs clang (libFuzzer): use the 'fuzz' preset")
  endif()
  set(_fuzz_san -fsanitize=address,undefined -fno-sanitize-recover=all -fno-omit-frame-pointer)
  target_compile_options(octshape_sanitizers INTERFACE ${_fuzz_san} -fsanitize=fuzzer-no-link)
  target_link_options(octshape_sanitizers INTERFACE ${_fuzz_san})
endif()

# Every first-party target calls this once.
# BUILD_INTERFACE: the flags are the build's own; an installed static library (libmesh, through
# find_package) asks nothing of its consumer's flags.
function(octshape_target_defaults target)
  target_link_libraries(${target} PRIVATE $<BUILD_INTERFACE:octshape_warnings>
    $<BUILD_INTERFACE:octshape_sanitizers>)
endfunction()
