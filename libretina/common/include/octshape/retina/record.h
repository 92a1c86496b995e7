#pragma once
// The record: every name a user's script reads, defined once (docs/outputs.md, docs/cohort.md).
//
// - the keys of a per-eye JSON's "cohort" record and its slim part (what a cohort keeps of an
//   eye: "cohort", "input", "csv_row");
// - the columns of every per-eye table (eyes.csv, eyes_onh.csv, `octshape merge`), in order:
//   the identifier columns, then the analysis's parameter columns (cube_csv_header +
//   etdrs_csv_header, onh_csv_header), then the columns that describe the scan;
// - the rows' sort keys; the failures and private inputs tables;
// - the scan type, as retina::ScanType (its name: to_string(ScanType), scan_type.h).
//
// Writers (cohort, cohort-eye, cohort tables, merge) and readers (stats, the gallery, the R
// recipe's documentation test) take the names from here, never as literals, so that renaming a
// column here renames it everywhere (tests/retina/record_test.cpp renames one and reads back).

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "octshape/retina/scan_type.h"

namespace octshape::retina::record {

// Every name of the record.
enum class Name : std::uint8_t {
    // The slim part of a per-eye JSON.
    kCohort,
    kInput,
    kCsvRow,
    // Identifier columns of a per-eye table (and keys of the "cohort" record).
    kSubjectId,
    kEye,
    kVisitDate,
    kScanType,
    kEyeKey,
    kSha256,
    kGroup,
    // Other keys of the "cohort" record.
    kSizeBytes,
    kMtimeNs,
    kOptions,
    kFingerprint,
    // What the scan was and which analysis read it: a per-eye table's rows of different
    // analyses are never pooled (stats keeps one analysis).
    kAnalysis,
    kScanPattern,
    kNumBscans,
    // failures.csv and the private inputs table.
    kFile,
    kReason,
    kExitCode,
    kResult,
    kCount_
};

// The name as written (a JSON key or a column header).
[[nodiscard]] const std::string& name(Name n);
[[nodiscard]] std::vector<std::string> names(const std::vector<Name>& ns);

// The identifier columns that lead every per-eye table, in order: subject_id, eye, visit_date,
// scan_type, eye_key, sha256, group.
[[nodiscard]] const std::vector<Name>& eyes_id_columns();
// The columns appended after the analysis's parameter columns, in order: scan_pattern,
// num_bscans (from the "cohort" record).
[[nodiscard]] const std::vector<Name>& eyes_scan_columns();
// The rows' order: subject_id, eye, visit_date, eye_key.
[[nodiscard]] const std::vector<Name>& eyes_sort_columns();
// Every column of a per-eye table that is not a parameter (stats never tabulates them): the
// identifiers, analysis, the scan columns and the fingerprint of `merge --allow-mixed`.
[[nodiscard]] std::vector<std::string> eyes_non_parameter_columns();
// The slim part of a per-eye JSON a cohort keeps and merge reads: cohort, input, csv_row.
[[nodiscard]] const std::vector<Name>& slim_keys();

// The header of a per-eye table: identifiers, `type_columns`, scan columns (+ fingerprint).
[[nodiscard]] std::vector<std::string> eyes_header(const std::vector<std::string>& type_columns,
                                                   bool fingerprint_column);
// One eye's row: its values by column name (a column absent from the map is "NA").
using Row = std::map<std::string, std::string>;
// The CSV text of a per-eye table: the header line, then the rows laid out in `header`'s order
// and sorted by eyes_sort_columns() (stable).
[[nodiscard]] std::string eyes_table(const std::vector<std::string>& header,
                                     const std::vector<Row>& rows);

// failures.csv: eye_key, reason, exit_code (the private copy: eye_key, file, reason, exit_code).
[[nodiscard]] std::vector<std::string> failures_columns(bool with_paths);
// OUTDIR/private/inputs.csv: eye_key, file, sha256, result.
[[nodiscard]] std::vector<std::string> inputs_columns();

// The per-eye table of a scan type in a cohort folder: eyes.csv (macula), eyes_onh.csv (onh).
[[nodiscard]] std::string eyes_table_file(ScanType t);
// The scan type of a name ("macula", "onh": to_string(ScanType)); nullopt for any other.
[[nodiscard]] std::optional<ScanType> parse_scan_type(std::string_view s);

namespace testing {
// Tests only: renames `n` while the object lives, so that a test sees every writer and reader
// follow one renamed column. Not thread-safe; never used by the program.
class ScopedRename {
public:
    ScopedRename(Name n, std::string renamed);
    ~ScopedRename();
    ScopedRename(const ScopedRename&) = delete;
    ScopedRename& operator=(const ScopedRename&) = delete;

private:
    Name n_;
    std::string previous_;
};
}  // namespace testing

}  // namespace octshape::retina::record
