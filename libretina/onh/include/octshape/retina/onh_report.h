#pragma once
// The per-eye ONH outputs: the JSON object and the CSV row (docs/outputs.md, "onh", documents
// every key and column). Missing values are JSON null and CSV "NA"; units are in every name.

#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "octshape/retina/onh.h"

namespace octshape::retina {

// "analysis", "orientation", "options", "parameters", "bmo", "bmo_points", "qc", "qc_flags" and
// "notes" of one eye.
// `options`: the caller's list of the effective options (under the command line's names, the
// same list as the provenance's); "sources" says where the ILM and the BMO came from
// (`ilm_source`, `bmo_source`, as the CSV's columns).
[[nodiscard]] nlohmann::ordered_json onh_json(const OnhResult& r,
                                              const nlohmann::ordered_json& options);

// Stable CSV columns (one header line, one row per eye), without the leading file/sha256/eye
// columns the caller adds.
[[nodiscard]] std::vector<std::string> onh_csv_header();
[[nodiscard]] std::vector<std::string> onh_csv_values(const OnhResult& r);

// The ONH's key parameters, the few the QC gallery shows per eye (the rest stay in the JSON):
// columns of onh_csv_header() and keys of the JSON's "parameters", in the page's order
// (tests/retina/record_test.cpp checks that each is a column).
[[nodiscard]] const std::vector<std::string>& onh_key_columns();

}  // namespace octshape::retina
