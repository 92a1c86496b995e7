#pragma once
// Statistics over a cohort's eyes.csv (docs/stats.md): the per-group table of every numeric
// parameter (thesis Tables 7.3 and 8.2: mean (SD), min-max) and the test-retest ICC(2,1) of
// repeated scans of the same eye (Tables 7.1 and 8.1).
//
// eyes.csv (docs/outputs.md): one header line, the columns of octshape/retina/record.h (the
// identifiers subject_id, eye, visit_date, scan_type, eye_key, sha256, group, then the
// parameters, then scan_pattern, num_bscans); "NA" (or an empty field) is missing.

#include <cstddef>
#include <istream>
#include <string>
#include <vector>

#include "octshape/io/csv.h"
#include "octshape/retina/record.h"
#include "octshape/retina/stats.h"

namespace octshape::retina {

// A CSV table of strings (io/csv.h, the project's one CSV dialect).
using EyeTable = io::CsvTable;

// Parses a CSV table. `name` is used in errors. Throws InputError::corrupt (with the line) on
// an unterminated quote, a row with the wrong number of fields or an empty/duplicate header.
[[nodiscard]] EyeTable read_eye_table(std::istream& in, const std::string& name);
// Opens and parses a file (InputError missing/unreadable when it cannot be read).
[[nodiscard]] EyeTable read_eye_table_file(const std::string& path);

// Columns that identify or describe a scan, never treated as parameters
// (record::eyes_non_parameter_columns(): the identifiers, analysis, scan_pattern, num_bscans,
// fingerprint).
[[nodiscard]] std::vector<std::string> eye_table_id_columns();

// True when the field is missing: "NA" or empty.
[[nodiscard]] bool is_missing_field(const std::string& s);

// The parameter columns: every column that is not an identifier (nor `group_column`) whose
// non-missing fields all parse completely as finite numbers, with at least one such field.
[[nodiscard]] std::vector<std::string> numeric_columns(const EyeTable& t,
                                                       const std::string& group_column);

struct GroupStatsParams {
    std::string group_column = record::name(record::Name::kGroup);  // absent -> one group "all"
    // false: one scan per eye (subject_id + eye), the first by visit_date then eye_key, as the
    // R recipe does; true: every row counts.
    bool all_scans = false;
    void validate() const;  // throws UsageError naming the bad field
};

struct GroupInfo {
    std::string name;      // "(none)" for rows whose group is missing
    std::size_t rows = 0;  // scans used
    std::size_t eyes = 0;  // distinct subject_id + eye
    std::size_t subjects = 0;
};

struct ParameterSummaries {
    std::string parameter;
    std::vector<Summary> per_group;  // same order as GroupStats::groups
};

struct GroupStats {
    std::string group_column;
    bool all_scans = false;
    std::vector<GroupInfo> groups;               // sorted by name (as R's factor levels)
    std::vector<ParameterSummaries> parameters;  // in column order
};

// Per group and parameter: n, mean (SD), min, max. Throws InputError::corrupt if a required
// identifier column (subject_id, eye, visit_date, eye_key) is missing.
[[nodiscard]] GroupStats group_stats(const EyeTable& t, const GroupStatsParams& p);

struct RetestParams {
    // false: repeats are all scans of the same eye (subject_id + eye) over any visit, in
    // visit_date then eye_key order; true: only scans of the same visit (subject_id + eye +
    // visit_date) are repeats of each other.
    bool same_visit = false;
    // k, the scans per eye used; 0 = the smallest number of scans among the eyes scanned more
    // than once. Eyes with fewer than k scans are left out, those with more use their first k.
    int sessions = 0;
    IccParams icc;
    void validate() const;  // throws UsageError naming the bad field
};

struct ParameterIcc {
    std::string parameter;
    std::size_t eyes_missing = 0;  // repeated eyes left out because a value is NA
    IccResult icc;                 // icc.n = eyes used; NaN when fewer than 2
};

struct RetestStats {
    bool same_visit = false;
    int k = 0;                      // scans per eye (columns of the ICC matrix)
    std::size_t repeated_eyes = 0;  // eyes (or eye-visits) with >= 2 scans
    std::size_t eyes_used = 0;      // of those, with >= k scans
    std::vector<ParameterIcc> parameters;
};

// ICC(2,1) per parameter over the repeated eyes. Throws AnalysisError when no eye has two
// scans, InputError::corrupt on missing identifier columns.
[[nodiscard]] RetestStats retest_stats(const EyeTable& t,
                                       const RetestParams& p,
                                       const std::string& group_column);

}  // namespace octshape::retina
