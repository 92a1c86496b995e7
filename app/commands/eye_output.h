#pragma once
// What every per-eye command (macula, onh) writes around its own results: the JSON preamble
// (version, command, input path + SHA-256, scan summary without identifiers), the leading CSV
// columns, and the atomic publication of the JSON and CSV files (or the JSON on stdout).

#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "octshape/io/scan.h"

namespace octshape::app {

// {"octshape_version", "command", "input": {"path", "sha256"}, "scan": summary}.
[[nodiscard]] nlohmann::ordered_json eye_json_preamble(const std::string& command,
                                                       const std::string& file,
                                                       const std::string& sha256,
                                                       const io::Scan& scan);

// Leading CSV columns of every per-eye row: file, sha256, eye, scan_pattern, num_bscans.
[[nodiscard]] std::vector<std::string> eye_csv_header();
[[nodiscard]] std::vector<std::string> eye_csv_values(const std::string& file,
                                                      const std::string& sha256,
                                                      const io::Scan& scan);

// Writes the CSV (header line + one row) and then the JSON, each atomically; with neither
// path given, prints the JSON on stdout. Throws OutputError.
void publish_eye_outputs(const std::string& json_out,
                         const std::string& csv_out,
                         const nlohmann::ordered_json& j,
                         const std::vector<std::string>& csv_header,
                         const std::vector<std::string>& csv_values);

}  // namespace octshape::app
