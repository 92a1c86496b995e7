#pragma once
// Where the binary came from: the source revision it was built from (git, at configure and at
// every build; "unknown" when built outside a git work tree, e.g. from a release tarball),
// whether tracked files differed from that revision ("yes", "no" or "unknown") and the CMake
// build type. Defined in the generated build_info.cpp (cmake/BuildInfo.cmake).

namespace octshape::app {

struct BuildInfo {
    const char* revision;  // git rev-parse --short=12 HEAD, or "unknown"
    const char* describe;  // git describe --always --tags, or "unknown"
    const char* modified;  // "yes" | "no" | "unknown"
    const char* build_type;
};

[[nodiscard]] const BuildInfo& build_info();

}  // namespace octshape::app
