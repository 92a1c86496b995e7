#pragma once
// Small helpers shared by the per-eye reports (cube_report.h, onh_report.h): how a number is
// written in JSON (missing: null) and, from io/csv.h, in CSV (missing: "NA"); and in a message.

#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "octshape/io/csv.h"

namespace octshape::retina {

// A finite number, or null.
[[nodiscard]] nlohmann::ordered_json json_number(double v);
// A registration's per-B-scan series (from B-scan 0): j["shift_um"] = the shifts,
// j["estimated"] = whether each was estimated (false beyond `estimated`'s end).
void put_shifts(nlohmann::ordered_json& j, const std::vector<double>& shift_um,
                const std::vector<bool>& estimated);
// `v` with `digits` decimals ("%.*f"), for messages and notes.
[[nodiscard]] std::string fixed_number(double v, int digits);
// The CSV writers are io's (octshape/io/csv.h, the one CSV dialect), named here for the reports.
using io::csv_field;
using io::csv_line;
using io::csv_number;

}  // namespace octshape::retina
