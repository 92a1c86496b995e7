# Warnings go through an INTERFACE target that every octshape target links, never global flags,
# so third-party headers and consumers of the libraries are not affected.
add_library(octshape_warnings INTERFACE)
target_compile_options(octshape_warnings INTERFACE
  $<$<CXX_COMPILER_ID:GNU,Clang>:-Wall -Wextra -Wpedantic -Wshadow -Wnon-virtual-dtor
    -Wcast-align -Woverloaded-virtual -Wnull-dereference -Wimplicit-fallthrough>
  $<$<BOOL:${OCTSHAPE_WERROR}>:-Werror>)
