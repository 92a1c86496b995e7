#pragma once
// Command-line mistakes as one line (docs/outputs.md, "Command-line mistakes"): CLI11's own
// texts ("The following arguments were not expected: ...", "A subcommand is required", several
// lines with "Run with --help") become `octshape: error: COMMAND: WHAT`, with a "did you mean"
// for a near miss of a command or option name.

#include <string>
#include <vector>

namespace CLI {
class App;
class ParseError;
}  // namespace CLI

namespace octshape::app {

// The one line (without "octshape: error: " and the newline) for a CLI11 parse error of `app`.
[[nodiscard]] std::string usage_error_line(const CLI::App& app, const CLI::ParseError& e);

// The candidate nearest `word` (edit distance at most max(1, |word| / 3), or one name a prefix
// of the other with at least two characters in common); empty when none is near.
[[nodiscard]] std::string nearest_name(const std::string& word,
                                       const std::vector<std::string>& candidates);

}  // namespace octshape::app
