# AddressSanitizer + UndefinedBehaviorSanitizer for the test preset: every octshape target and
# the test runner are instrumented; UB aborts instead of printing and carrying on.
add_library(octshape_sanitizers INTERFACE)
if(OCTSHAPE_SANITIZE)
  set(_san -fsanitize=address,undefined -fno-sanitize-recover=all -fno-omit-frame-pointer)
  target_compile_options(octshape_sanitizers INTERFACE ${_san})
  target_link_options(octshape_sanitizers INTERFACE ${_san})
endif()

# Every first-party target calls this once.
function(octshape_target_defaults target)
  target_link_libraries(${target} PRIVATE octshape_warnings octshape_sanitizers)
endfunction()
