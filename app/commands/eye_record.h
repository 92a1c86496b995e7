#pragma once
// What a per-eye result records for cohorts (docs/cohort.md): the subject pseudonym, the visit
// date, the file facts that let a re-run recognise a finished eye without rehashing, and the
// table builder that turns per-eye JSON objects into eyes.csv (`octshape merge` and
// `octshape cohort` share it).

#include <cstdint>
#include <filesystem>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "octshape/io/scan.h"
#include "octshape/retina/scan_type.h"

namespace CLI {
class App;
}  // namespace CLI

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
    // The subject id of a patient ID (`octshape pseudonym`, groups files keyed by patient ID);
    // nullopt when the source has none for it. Throws UsageError for a source keyed by file.
    [[nodiscard]] std::optional<std::string> of_patient(const std::string& patient_id) const;

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

// The eye key of an input: the first 16 hex digits of HMAC-SHA256(secret, absolute normalised
// path) under the cohort's own secret (OUTDIR/private/eye.key, set_eye_key_secret), so that
// nobody without that file can recompute it from a list of patients' paths; a single-eye command
// (no cohort, no secret set) uses SHA-256 of the path. It names the eye's records and QC
// pictures and is the eyes table's key column, so that no output meant for sharing holds a
// file or folder name (docs/cohort.md).
[[nodiscard]] std::string eye_key(const std::string& absolute_path);
// The same under an explicit secret (empty: the unkeyed SHA-256 form).
[[nodiscard]] std::string eye_key(const std::string& absolute_path, const std::string& secret);
// Sets the secret of every later eye_key(path) of this process (and of its forked workers): the
// cohort commands set it once, before any eye is keyed.
void set_eye_key_secret(std::string secret);
// The random bytes of the keys a cohort makes for itself (OUTDIR/private/eye.key, subject.key):
// 256 bits, written as one line of 64 lowercase hex digits.
inline constexpr std::size_t kKeyFileBytes = 32;
// Reads such a key file. Anything but one line of 64 lowercase hex digits is a damaged file:
// InputError (exit 65), since a key made anew would silently give every eye (or subject) of the
// folder other keys.
[[nodiscard]] std::string read_key_file(const std::string& path);
// `--eye-key-file F` of `macula` and `onh`: eye keys under a cohort's OUTDIR/private/eye.key, so
// that `merge` of per-scan results gives that cohort's keys (without it: SHA-256 of the path).
void add_eye_key_option(CLI::App* cmd, std::string& file);

// How a log line names an input: "eye KEY" (or "mesh KEY", `noun`) with its eye key, never its
// path: Heidelberg names exports after the patient, and logs are kept and shared. With -v
// (debug level) the path is logged beside the key, for the person at the terminal. Error
// messages (one line naming the file, to the terminal) keep the path.
[[nodiscard]] std::string log_name(const std::string& file, const char* noun = "eye");

// ---- File facts and the resume record ----------------------------------------------------

struct FileFacts {
    std::string path;         // absolute, lexically normal
    std::uintmax_t size = 0;  // bytes
    std::int64_t mtime_ns = 0;
};
// Throws InputError if the file cannot be stat'ed.
[[nodiscard]] FileFacts file_facts(const std::string& file);
[[nodiscard]] std::string absolute_path(const std::string& file);

// The "cohort" object of a per-eye JSON (and of a failure record): the eye key (never the
// path), the file's size and mtime, the parameter text and its fingerprint
// (commands/provenance.h), the scan type ("unknown" for nullopt: a failure); the names are the
// record's (octshape/retina/record.h).
[[nodiscard]] nlohmann::ordered_json cohort_record(const FileFacts& facts,
                                                   const std::string& options_text,
                                                   std::optional<retina::ScanType> scan_type);
// Whether a record still stands for this file and this binary's parameters.
enum class RecordState {
    kCurrent,             // same eye key, file size and mtime, same fingerprint
    kFileChanged,         // another file (key), or the file changed (size, mtime)
    kFingerprintChanged,  // same file, but other code or parameters made it
};
[[nodiscard]] RecordState record_state(const nlohmann::json& record,
                                       const FileFacts& facts,
                                       const std::string& options_text);
// True when `record` (a "cohort" object) is kCurrent: the eye need not be redone.
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
// and `j["cohort"]` (cohort_record + subject id, visit date, eye, scan pattern, number of
// B-scans).
void attach_cohort_record(nlohmann::ordered_json& j,
                          const std::vector<std::string>& type_columns,
                          const std::vector<std::string>& type_values,
                          const FileFacts& facts,
                          const std::string& options_text,
                          retina::ScanType scan_type,
                          const io::Scan& scan,
                          const SubjectSource& subjects,
                          const std::string& file);

// ---- eyes.csv -----------------------------------------------------------------------------

// `--groups map.csv`: header `subject_id,group`, `patient_id,group` (a clinician's private
// file: each patient ID is turned into its subject id with `subjects`, so no table needs the
// ID) or `file,group` (absolute path or file name; needs the inputs' paths, which only
// `octshape cohort` has: set_paths). Throws InputError when unreadable or malformed,
// UsageError when `subjects` cannot turn patient IDs into subject ids.
class GroupMap {
public:
    GroupMap() = default;
    static GroupMap load(const std::string& path, const SubjectSource& subjects);
    // Eye key -> absolute path of the inputs (for a map keyed by file).
    void set_paths(std::map<std::string, std::string> paths) { paths_ = std::move(paths); }
    [[nodiscard]] bool by_file() const { return key_ == "file"; }
    [[nodiscard]] bool empty() const { return path_.empty(); }
    [[nodiscard]] const std::string& path() const { return path_; }  // empty: no groups file
    // "NA" when unmapped (or no map). Counts the eyes asked about and those matched.
    [[nodiscard]] std::string group_of(const std::string& subject_id,
                                       const std::string& eye_key) const;
    // After the tables are built: a map that matched none of the eyes asked about (if any) is
    // an InputError naming the file; a partial match is one warning with the counts.
    void check_matches() const;

private:
    std::string path_;
    std::string key_ = "subject_id";  // subject_id | file (patient IDs are turned into subjects)
    std::map<std::string, std::string> map_;
    std::map<std::string, std::string> paths_;
    [[nodiscard]] std::string lookup(const std::string& subject_id,
                                     const std::string& eye_key) const;
    mutable std::size_t asked_ = 0;
    mutable std::size_t matched_ = 0;
};

// Eye key -> input path from a private inputs table (header eye_key,file[,...]: the cohort's
// OUTDIR/private/inputs.csv, or the workflow's). Throws InputError when unreadable/malformed.
[[nodiscard]] std::map<std::string, std::string> load_input_paths(const std::string& path);

// Per-type parameter columns (macula: retina::cube_csv_header() + etdrs_csv_header(), onh:
// retina::onh_csv_header()).
[[nodiscard]] std::vector<std::string> eyes_type_header(retina::ScanType scan_type);

// Builds the CSV (retina::record::eyes_header and eyes_table: the record's columns and sort
// keys) of the eyes of `scan_type` among `eyes` (per-eye JSON objects with a "cohort" record
// and a "csv_row").
// Throws InputError naming `names[i]` when an object lacks what the table needs. Checks the
// `fingerprint_column`: a last column with
// each eye's fingerprint (`octshape merge --allow-mixed`).
[[nodiscard]] std::string eyes_csv(const std::vector<nlohmann::json>& eyes,
                                   const std::vector<std::string>& names,
                                   retina::ScanType scan_type,
                                   const GroupMap& groups,
                                   bool fingerprint_column = false);

// Reads per-eye JSON files (InputError when unreadable or not JSON).
[[nodiscard]] nlohmann::json read_json_file(const std::string& path);

}  // namespace octshape::app
