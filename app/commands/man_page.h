#pragma once
// The manual page octshape(1), made from the same CLI11 objects that print `--help`: the main
// help, then every command's (and every `phantom` command's) help text, then the exit codes
// of the footer as the EXIT STATUS section. The build writes it (`octshape --man-page`,
// cmake/ManPage.cmake) and `cmake --install` puts it in share/man/man1.

#include <string>

namespace CLI {
class App;
}  // namespace CLI

namespace octshape::app {

// The roff source of octshape(1). `footer` is the text every --help ends with (the exit codes,
// one "  CODE  meaning" line each, then free text).
[[nodiscard]] std::string man_page(const CLI::App& app, const std::string& footer,
                                   const std::string& version);

}  // namespace octshape::app
