#pragma once
// The per-eye CuBe outputs: the JSON object and the CSV row (docs/outputs.md documents every
// column). Missing values are JSON null and CSV "NA"; units are in every name.

#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "octshape/retina/cube.h"
#include "octshape/retina/report_util.h"  // csv_field

namespace octshape::retina {

// "parameters", "centre", "half_lines", "qc_flags", "notes", "options", "sampling" and
// "orientation" of one eye. Line scans omit the 3-D parameters and say so in "notes".
// `options` is the caller's list of the effective options (under the command line's names, the
// same list as the provenance's); "sampling" holds what the scan resolved: the half-lines
// fitted (`half_lines`: 2 for a line scan, 2 per line for a radial one) and the radial sample
// spacing (`spacing_mm`: ScaleX when the option is 0).
[[nodiscard]] nlohmann::ordered_json cube_json(const CubeResult& r, const CubeParams& p,
                                               const nlohmann::ordered_json& options);

// Stable CSV columns (one header line, one row per eye), without the leading file/sha256/eye
// columns the caller adds.
[[nodiscard]] std::vector<std::string> cube_csv_header();
[[nodiscard]] std::vector<std::string> cube_csv_values(const CubeResult& r);

// The macula's parameter columns of every per-eye table (the `macula --csv` row after the scan
// columns, eyes.csv after the record's identifiers): cube_csv_header(), then
// etdrs_csv_header() (etdrs.h). A new ETDRS column (e.g. the sectors at the scan centre) is
// added in etdrs_csv_header and etdrs_csv_values, appended at their end, and nowhere else: the
// tables, `merge`, `stats` and the documentation test (tests/retina/record_test.cpp) follow.
[[nodiscard]] std::vector<std::string> macula_csv_header();

// The macula's key parameters, the few the QC gallery shows per eye (the rest stay in the
// JSON): columns of macula_csv_header() and keys of the JSON's "parameters", in the page's
// order (tests/retina/record_test.cpp checks that each is a column).
[[nodiscard]] const std::vector<std::string>& macula_key_columns();

}  // namespace octshape::retina
