#pragma once
// What a per-eye result records for cohorts (docs/cohort.md): the subject pseudonym, the visit
// date, the file facts that let a re-run recognise a finished eye without rehashing, and the
// table builder that turns per-eye JSON objects into eyes.csv (`octshape merge` and
// `octshape cohort` share it).

#include <CLI/CLI.hpp>
#include <cstdint>
#include <filesystem>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "octshape/io/scan.h"

namespace octshape::app {

// ---- Subject pseudonyms -------------------------------------------------------------------

// Command-line choices; at most one source may be given.
struct SubjectOptions {
    std::string key;       // --subject-key KEY: HMAC-SHA256 key (visible in `ps`: prefer a file)
    std::string key_file;  // --subject-key-file F: the key is the file's first line
    std::string map_file;  // --subjects map.csv: header file,subject_id or patient_id,subject_id
    std::string mode;      // --subject-id raw: the export's patient ID as is (explicit request)
};

void add_subject_options(CLI::App* cmd, SubjectOptions& options);

class SubjectSource {
public:
    enum class Kind { kNone, kKeyedHash, kMap, kRaw };
    // Loads the key file or the map; throws UsageError (two sources, empty key, bad --subject-id)
    // or InputError (key/map file unreadable or malformed).
    static SubjectSource from_options(const SubjectOptions& options);

    [[nodiscard]] Kind kind() const { return kind_; }
    // The subject id of an eye; nullopt (CSV "NA") when the source has none for it.
    // `file` is the absolute path as recorded.
    [[nodiscard]] std::optional<std::string> subject_id(const io::Scan& scan,
                                                        const std::string& file) const;
    // Identifies the settings without revealing the key (part of the resume signature):
    // e.g. "hmac:" + HMAC(key, "octshape subject key check")[0..16].
    [[nodiscard]] std::string fingerprint() const { return fingerprint_; }

private:
    Kind kind_ = Kind::kNone;
    std::string key_;
    std::map<std::string, std::string> by_file_;     // absolute path or file name -> subject
    std::map<std::string, std::string> by_patient_;  // patient ID -> subject
    std::string fingerprint_ = "none";
};

// Number of hex characters kept of the HMAC (64 bits: a collision among 10^5 subjects has
// probability ~ n^2 / 2^65 < 1e-9).
inline constexpr std::size_t kSubjectHexChars = 16;

// The patient ID a pseudonym is derived from: PatientID, else ID; empty if the export has none.
[[nodiscard]] std::string patient_key(const io::Scan& scan);
// ISO date of the visit (VisitDate, else the exam time's date); nullopt if the export has none.
[[nodiscard]] std::optional<std::string> visit_date(const io::Scan& scan);

// ---- File facts and the resume record ----------------------------------------------------

struct FileFacts {
    std::string path;         // absolute, lexically normal
    std::uintmax_t size = 0;  // bytes
    std::int64_t mtime_ns = 0;
};
// Throws InputError if the file cannot be stat'ed.
[[nodiscard]] FileFacts file_facts(const std::string& file);
[[nodiscard]] std::string absolute_path(const std::string& file);

// The "cohort" object of a per-eye JSON (and of a failure record).
[[nodiscard]] nlohmann::ordered_json cohort_record(const FileFacts& facts,
                                                   const std::string& options_text,
                                                   const std::string& scan_type);
// True when `record` (a "cohort" object) was made from this file state with these options by
// this octshape version: the eye need not be redone.
[[nodiscard]] bool record_is_current(const nlohmann::json& record,
                                     const FileFacts& facts,
                                     const std::string& options_text);

// The per-eye outputs of any analysis (macula, onh): the JSON object with its "cohort" record
// and "csv_row", and the single-eye CSV (header + row) of `octshape macula|onh --csv`.
struct EyeResult {
    nlohmann::ordered_json json;
    std::vector<std::string> csv_header;
    std::vector<std::string> csv_row;
};

// Completes an eye's result for cohorts: `j["csv_row"]` (the `type_columns` of the row by name)
// and `j["cohort"]` (cohort_record + subject id, visit date, eye).
void attach_cohort_record(nlohmann::ordered_json& j,
                          const std::vector<std::string>& type_columns,
                          const std::vector<std::string>& type_values,
                          const FileFacts& facts,
                          const std::string& options_text,
                          const std::string& scan_type,
                          const io::Scan& scan,
                          const SubjectSource& subjects,
                          const std::string& file);

// ---- eyes.csv -----------------------------------------------------------------------------

// `--groups map.csv`: header `subject_id,group` or `file,group` (file = absolute path or file
// name). Throws InputError when unreadable or malformed.
class GroupMap {
public:
    GroupMap() = default;
    static GroupMap load(const std::string& path);
    // "NA" when unmapped (or no map).
    [[nodiscard]] std::string group_of(const std::string& subject_id,
                                       const std::string& file) const;

private:
    bool by_subject_ = true;
    std::map<std::string, std::string> map_;
};

// The leading columns of every eyes table.
[[nodiscard]] std::vector<std::string> eyes_common_header();
// Per-type parameter columns ("macula": retina::cube_csv_header(), "onh":
// retina::onh_csv_header()).
[[nodiscard]] std::vector<std::string> eyes_type_header(const std::string& scan_type);

// Builds the CSV (header + rows sorted by subject_id, eye, visit_date, file) of the eyes of
// `scan_type` among `eyes` (per-eye JSON objects with a "cohort" record and a "csv_row").
// Throws InputError naming `names[i]` when an object lacks what the table needs.
[[nodiscard]] std::string eyes_csv(const std::vector<nlohmann::json>& eyes,
                                   const std::vector<std::string>& names,
                                   const std::string& scan_type,
                                   const GroupMap& groups);

// Reads per-eye JSON files (InputError when unreadable or not JSON).
[[nodiscard]] nlohmann::json read_json_file(const std::string& path);

}  // namespace octshape::app
