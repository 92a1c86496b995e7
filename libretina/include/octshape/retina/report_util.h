#pragma once
// Small helpers shared by the per-eye reports (cube_report.h, onh_report.h): how a number is
// written in JSON and CSV, and CSV quoting. Missing values are JSON null and CSV "NA".

#include <nlohmann/json.hpp>
#include <string>
#include <vector>

namespace octshape::retina {

// A finite number, or null.
[[nodiscard]] nlohmann::ordered_json json_number(double v);
// A finite number with 10 significant digits, or "NA".
[[nodiscard]] std::string csv_number(double v);
// Quotes a CSV field when it holds a comma, quote or newline (RFC 4180).
[[nodiscard]] std::string csv_field(const std::string& s);
// One CSV line (fields quoted as needed, '\n' at the end).
[[nodiscard]] std::string csv_line(const std::vector<std::string>& fields);

}  // namespace octshape::retina
