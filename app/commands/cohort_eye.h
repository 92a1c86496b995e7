#pragma once
// The per-eye unit of `octshape cohort` (docs/cohort.md): what one input becomes in a cohort
// output folder. `octshape cohort` runs it in its worker processes, `octshape cohort-eye` (one
// Snakemake/Slurm job per input) runs the same code on one file, so both write the same per-eye
// JSON, failure records and QC pictures under the same eye key.

#include <filesystem>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "commands/eye_record.h"
#include "commands/macula_eye.h"
#include "commands/onh_eye.h"
#include "octshape/retina/record.h"

namespace octshape::app {

// The options of a cohort run (`octshape cohort`, `cohort-eye`, `cohort-tables`).
struct CohortOptions {
    std::vector<std::string> inputs;
    std::string out;
    int jobs = 0;  // 0: one per core
    std::string groups;
    std::string type = "auto";
    bool qc = false;
    bool retry_failed = false;
    double eye_timeout_s = 600.0;  // an eye still running after this is stopped; 0: no limit
    MaculaEyeOptions eye;
    OnhEyeOptions onh;
    SubjectOptions subjects;
};

// One input file and what is known about it.
struct Item {
    std::string path;  // absolute
    std::string key;   // eye_key(path): HMAC under the cohort's eye.key
    FileFacts facts;
    bool done = false;       // a current result exists
    bool failed = false;     // a current failure record exists
    bool refingerprinted = false;  // its result was made by other code or parameters
    nlohmann::json slim;     // what eyes.csv needs of the result
    nlohmann::json failure;  // the failure record
    // Nothing left to do for this input: a current result or a current failure record (set by
    // load_item on resume, by take_result or record_failure during the run).
    [[nodiscard]] bool settled() const { return done || failed; }
};

// A file that could not be taken in: path, eye key, reason, exit code.
struct Skipped {
    std::string path;
    std::string key;  // eye_key(path)
    std::string reason;
    int exit_code = 0;
};

// A failure reason fit for OUTDIR/failures.csv: the input's path, file name, stem and folder
// name replaced by "<input>" (they are in OUTDIR/private/failures.csv).
[[nodiscard]] std::string scrub(std::string reason, const std::string& abs_path);

// OUTDIR/private/ (mode 0700): everything that names an input (docs/cohort.md, "Output
// folder"). Made when missing.
std::filesystem::path make_private_dir(const std::filesystem::path& out);

// The subject key of a cohort run without a subject option: OUTDIR/private/subject.key, made
// (64 hex digits of RAND_bytes, mode 0600) by the first command that needs it and reused by every
// later one; safe when several `cohort-eye` jobs make it at once (the first one's is kept).
// Returns its path.
std::string own_subject_key(const std::filesystem::path& private_dir);

// The secret of the cohort's eye keys (eye_key, set_eye_key_secret): OUTDIR/private/eye.key,
// made (64 hex digits of RAND_bytes, mode 0600) by the first cohort command on OUTDIR and
// reused by every later one (`cohort`, `cohort --list`, `cohort-eye`, `cohort-tables`), as the
// subject key. Returns the key; a damaged file is an InputError (exit 65), never replaced.
std::string own_eye_key(const std::filesystem::path& private_dir);

// The options of a cohort run's subject ids: `o.subjects`, or, when no subject option is given,
// the cohort's own key (own_subject_key) under OUTDIR/private/.
[[nodiscard]] SubjectOptions cohort_subject_options(const CohortOptions& o);

// The option texts a record must carry to count as current: an eye's, per scan type (changing
// an ONH option redoes the ONH eyes only), and a failure's (which also depends on --type, --qc
// and --eye-timeout-s).
struct CohortSignatures {
    std::string macula;
    std::string onh;
    std::string failure;
    [[nodiscard]] const std::string& eye(std::optional<retina::ScanType> scan_type) const {
        return scan_type == retina::ScanType::kOnh ? onh : macula;
    }
};
[[nodiscard]] CohortSignatures cohort_signatures(const CohortOptions& o,
                                                 const SubjectSource& subjects);

// What eyes.csv needs of a per-eye JSON (retina::record::slim_keys(); the rest stays on disk).
[[nodiscard]] nlohmann::json slim(const nlohmann::json& j);

// The resume check of one input: its item, marked done (with its slim result) or failed (with
// its record) when OUTDIR holds a current record of it; `refingerprinted` when its result was
// made by other code or parameters (a different fingerprint: redone). A file that cannot be stat'ed goes to
// `skipped` (nullopt).
// Where an eye's state lives in OUTDIR (its presence with a current record is what resume
// reads): OUTDIR/eyes/<key>.json, the result; OUTDIR/failures/<key>.json, a recorded failure.
[[nodiscard]] std::filesystem::path eye_result_file(const std::filesystem::path& out,
                                                    const std::string& key);
[[nodiscard]] std::filesystem::path eye_failure_file(const std::filesystem::path& out,
                                                     const std::string& key);

[[nodiscard]] std::optional<Item> load_item(const std::string& file,
                                            const std::filesystem::path& out,
                                            const CohortOptions& o, const CohortSignatures& sig,
                                            std::vector<Skipped>& skipped);

// One eye: classify, analyse as macula or ONH, write OUTDIR/eyes/<key>.json (and the QC
// pictures with --qc). Returns 0 when its JSON is written, else the failure's exit code and
// `message`. Never throws.
int analyse_eye(const CohortOptions& o, const SubjectSource& subjects, const Item& item,
                const std::filesystem::path& out, std::string& message);

// Writes OUTDIR/failures/<key>.json (its cohort record, reason, exit code); marks `item` failed.
void record_failure(Item& item, const std::filesystem::path& out,
                    const std::string& options_text, const std::string& reason, int exit_code);

// After analyse_eye returned 0: takes the eye's result for the tables and removes a failure
// record an earlier run left. False (with `reason`) when the result cannot be read back.
bool take_result(Item& item, const std::filesystem::path& out, std::string& reason);

}  // namespace octshape::app
