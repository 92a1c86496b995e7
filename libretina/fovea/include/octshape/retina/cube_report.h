#pragma once
// The per-eye CuBe outputs: the JSON object and the CSV row (docs/outputs.md documents every
// column). Missing values are JSON null and CSV "NA"; units are in every name.

#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "octshape/retina/cube.h"
#include "octshape/retina/report_util.h"  // csv_field

namespace octshape::retina {

// "parameters", "centre", "half_lines", "qc_flags", "notes", "options" and "orientation" of one
// eye. Line scans omit the 3-D parameters (SPEC §4.8) and say so in "notes".
[[nodiscard]] nlohmann::ordered_json cube_json(const CubeResult& r, const CubeParams& p);

// Stable CSV columns (one header line, one row per eye), without the leading file/sha256/eye
// columns the caller adds.
[[nodiscard]] std::vector<std::string> cube_csv_header();
[[nodiscard]] std::vector<std::string> cube_csv_values(const CubeResult& r);

}  // namespace octshape::retina
