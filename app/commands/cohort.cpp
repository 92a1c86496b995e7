// `octshape cohort DIR... -o OUTDIR`: every supported export under the folders, macula or ONH
// by scan content, N eyes at a time in N worker processes; resumable and crash safe. And the
// two halves of it that a Snakemake/Slurm workflow runs as separate jobs: `octshape cohort-eye`
// (one input, exactly as a cohort worker does it) and `octshape cohort-tables` (the tables from
// the records). Layout, resume rule and the crash-safety argument: docs/cohort.md.

#include <CLI/CLI.hpp>
#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <map>
#include <memory>
#include <random>
#include <nlohmann/json.hpp>
#include <thread>

#include "commands/command.h"
#include "commands/cohort_eye.h"
#include "commands/cohort_tables.h"
#include "commands/cohort_workers.h"
#include "commands/eye_record.h"
#include "commands/provenance.h"
#include "octshape/error.h"
#include "octshape/io/atomic_file.h"
#include "octshape/io/scan_reader.h"
#include "octshape/retina/scan_type.h"
#include "octshape/retina/record.h"

namespace octshape::app {
namespace {

namespace fs = std::filesystem;

// Holds a lock on OUTDIR/.lock for the whole run (released by the kernel even on SIGKILL):
// exclusive for `cohort` and `cohort-tables`, so two runs never write the same OUTDIR; shared
// for `cohort-eye`, so the jobs of a workflow run side by side but never beside a cohort run.
class DirLock {
public:
    DirLock(const fs::path& dir, bool exclusive) {
        const fs::path p = dir / ".lock";
        fd_ = ::open(p.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
        if (fd_ < 0) throw OutputError(p.string(), std::strerror(errno));
        if (::flock(fd_, (exclusive ? LOCK_EX : LOCK_SH) | LOCK_NB) != 0) {
            ::close(fd_);
            throw UsageError(dir.string() + ": another `octshape cohort` is writing this "
                             "folder (lock " + p.string() + ")");
        }
    }
    ~DirLock() { ::close(fd_); }
    [[nodiscard]] int fd() const { return fd_; }
    DirLock(const DirLock&) = delete;
    DirLock& operator=(const DirLock&) = delete;

private:
    int fd_ = -1;
};

void make_dir(const fs::path& d) {
    std::error_code ec;
    fs::create_directories(d, ec);
    if (ec || !fs::is_directory(d)) {
        throw OutputError(d.string(), "cannot create directory: " + ec.message());
    }
}

// Temporary files of writes that a kill interrupted (".NAME.tmp-PID-RANDOM"); with a `key`, only
// those of that eye (".KEY.json.tmp-...", ".KEY_thickness.png.tmp-...": other jobs may be
// writing theirs).
void remove_stale_temporaries(const fs::path& d, const std::string& key = "") {
    std::error_code ec;
    for (fs::directory_iterator it(d, ec), end; !ec && it != end; it.increment(ec)) {
        const std::string name = it->path().filename().string();
        if (name.size() > 1 && name.rfind("." + key, 0) == 0 &&
            name.find(".tmp-") != std::string::npos) {
            std::error_code rm;
            fs::remove(it->path(), rm);
        }
    }
}

bool has_export_extension(const fs::path& p) {
    std::string ext = p.extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(),
                   [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    return ext == ".vol" || ext == ".xml" || ext == ".fda" || ext == ".fds";
}

// Every regular file under the inputs whose content is a supported export, sorted, unique.
// A .vol/.xml/.fda/.fds file of unknown content and an unreadable file go to `skipped`; other files
// (TIFF B-scans of an XML export, notes, ...) are ignored.
std::vector<std::string> discover(const std::vector<std::string>& inputs, const fs::path& out,
                                  std::vector<Skipped>& skipped) {
    std::vector<std::string> files;
    const std::string out_abs = absolute_path(out.string());
    int segmentations = 0;
    auto consider = [&](const fs::path& p) {
        const std::string abs = absolute_path(p.string());
        if (abs.rfind(out_abs + "/", 0) == 0) return;  // our own outputs
        try {
            const io::FileFormat format = io::detect_format(abs);
            if (format == io::FileFormat::kIowaSurfaces) {
                // A segmentation of an export, which OCTExplorer writes beside it: analysing
                // both would count the eye twice.
                ++segmentations;
            } else if (format != io::FileFormat::kUnknown) {
                files.push_back(abs);
            } else if (has_export_extension(p)) {
                skipped.push_back({abs, eye_key(abs), "not a supported export (unknown content)",
                                   static_cast<int>(ExitCode::kDataError)});
            }
        } catch (const InputError& e) {
            skipped.push_back({abs, eye_key(abs), e.what(), static_cast<int>(e.exit_code())});
        }
    };
    for (const auto& in : inputs) {
        std::error_code ec;
        if (!fs::exists(in, ec)) throw InputError::missing(in);
        if (!fs::is_directory(in, ec)) {
            consider(in);
            continue;
        }
        fs::recursive_directory_iterator it(in, fs::directory_options::skip_permission_denied,
                                            ec);
        if (ec) throw InputError::unreadable(in, ec.message());
        for (const fs::recursive_directory_iterator end; it != end; it.increment(ec)) {
            if (ec) {
                skipped.push_back({absolute_path(in), eye_key(absolute_path(in)),
                                   "folder walk stopped: " + ec.message(),
                                   static_cast<int>(ExitCode::kNoInput)});
                break;
            }
            std::error_code sec;
            if (it->is_regular_file(sec)) consider(it->path());
        }
    }
    std::sort(files.begin(), files.end());
    files.erase(std::unique(files.begin(), files.end()), files.end());
    if (segmentations > 0) {
        spdlog::info("{} Iowa surfaces file(s) ignored: segmentations, not exports (analyse one "
                     "with `octshape macula FILE`, or over its export with --segmentation)",
                     segmentations);
    }
    return files;
}


// What every cohort command needs before it touches an eye (options checked).
struct Setup {
    SubjectSource subjects;
    GroupMap groups;
    CohortSignatures sig;
    int jobs = 1;
};

Setup prepare(CohortOptions& o) {
    if (o.type != "auto" && !retina::record::parse_scan_type(o.type)) {
        throw UsageError("--type must be auto, macula or onh");
    }
    if (o.jobs < 0) throw UsageError("--jobs must be >= 1");
    if (!(o.eye_timeout_s >= 0.0)) throw UsageError("--eye-timeout-s must be >= 0");
    Setup s;
    const int cores = static_cast<int>(std::thread::hardware_concurrency());
    s.jobs = o.jobs > 0 ? o.jobs : std::max(1, cores);  // 0: not given
    o.eye.params = effective_params(o.eye);
    for (const auto& in : o.inputs) {  // before anything is written
        std::error_code ec;
        if (!fs::exists(in, ec)) throw InputError::missing(in);
    }
    io::check_output_directory(o.out);
    // Without a subject option the cohort keys the pseudonyms with its own random key,
    // OUTDIR/private/subject.key: made by the first command on OUTDIR that needs it (`cohort`,
    // `cohort --list` before a workflow's jobs, or a `cohort-eye` job), reused by the others.
    s.subjects = SubjectSource::from_options(cohort_subject_options(o));
    // The eye keys: HMAC of each path under the cohort's own secret, OUTDIR/private/eye.key
    // (made here by the first command on OUTDIR, like the subject key; reused by the others).
    set_eye_key_secret(own_eye_key(make_private_dir(o.out)));
    if (!o.groups.empty()) s.groups = GroupMap::load(o.groups, s.subjects);
    // The eye record's options, and the failure record's (which also depend on --type).
    s.sig = cohort_signatures(o, s.subjects);
    return s;
}

// OUTDIR's sub-folders; stale temporaries of killed writes removed (only `key`'s if given).
void make_output_dirs(const fs::path& out, bool qc, const std::string& key = "") {
    for (const char* d : {"eyes", "failures"}) make_dir(out / d);
    if (qc) make_dir(out / "qc");
    const fs::path private_dir = make_private_dir(out);
    for (const auto& d : {out, out / "eyes", out / "failures", out / "qc", private_dir}) {
        remove_stale_temporaries(d, key);
    }
}

// Creates OUTDIR and takes its lock; with `dirs`, its sub-folders too (make_output_dirs).
std::unique_ptr<DirLock> open_output(const fs::path& out, bool exclusive, bool dirs, bool qc) {
    make_dir(out);
    auto lock = std::make_unique<DirLock>(out, exclusive);
    if (dirs) make_output_dirs(out, qc);
    return lock;
}

// The items of the inputs with their resume state; files that cannot be taken in go to
// `skipped`.
std::vector<Item> load_items(const CohortOptions& o, const Setup& s, const fs::path& out,
                             std::vector<Skipped>& skipped) {
    const auto files = discover(o.inputs, out, skipped);
    std::vector<Item> items;
    items.reserve(files.size());
    for (const auto& f : files) {
        auto it = load_item(f, out, o, s.sig, skipped);
        if (it) items.push_back(std::move(*it));
    }
    return items;
}

void run(CohortOptions& o, RunContext& ctx) {
    const Setup s = prepare(o);
    const fs::path out(o.out);
    const auto lock = open_output(out, /*exclusive=*/true, /*dirs=*/true, o.qc);

    std::vector<Skipped> skipped;
    std::vector<Item> items = load_items(o, s, out, skipped);
    std::vector<std::size_t> pending;
    for (std::size_t i = 0; i < items.size(); ++i) {
        if (!items[i].settled()) pending.push_back(i);
    }
    const std::size_t resumed = items.size() - pending.size();
    spdlog::info("{} exports found, {} already done (results or recorded failures), {} to do, "
                 "{} job(s){}",
                 items.size(), resumed, pending.size(), s.jobs,
                 skipped.empty() ? std::string()
                                 : "; " + std::to_string(skipped.size()) +
                                       " other file(s) named as exports are not readable "
                                       "exports (recorded as failures)");
    const auto refingerprinted = std::count_if(items.begin(), items.end(),
                                               [](const Item& it) { return it.refingerprinted; });
    if (refingerprinted > 0) {
        spdlog::info("{} eye(s) redone: their results were made by other code or parameters "
                     "(fingerprint differs from this binary's {})",
                     refingerprinted, version_text());
    }
    run_workers(o, s.subjects, items, pending, out, s.sig.failure, s.jobs, lock->fd());

    // Every record of this run reaches the disk before the tables that list them (one syncfs
    // instead of two fsyncs per eye); the tables are rebuilt from the records of this run's
    // inputs, each written atomically and durably.
    if (::syncfs(lock->fd()) != 0) throw OutputError(out.string(), std::strerror(errno));
    const CohortTables t = write_cohort_tables(out, items, skipped, s.groups, o.qc);
    if (t.failed > 0) ctx.exit_code = static_cast<int>(ExitCode::kPartial);
}

// `cohort --list`: one JSON line per input the run would analyse: its eye key, the scan type
// the analysis will take ("macula", "onh", or "unknown" when the classifier cannot read or
// classify it: the eye's job then records the failure) and the file. Writes nothing but, when
// no subject option is given, the cohort's own key OUTDIR/private/subject.key (made once here,
// before a workflow starts its eye jobs, which then all use it).
void list(CohortOptions& o) {
    const Setup s = prepare(o);
    const fs::path out(o.out);
    std::vector<Skipped> skipped;
    for (const auto& f : discover(o.inputs, out, skipped)) {
        std::string type = o.type;
        if (type == "auto") {
            try {
                // The classifier needs the BM segmentation only: no pixels, no hash.
                const auto c = retina::classify_scan(io::read_scan(f));
                type = c.type == retina::ScanType::kUnsupported ? "unknown"
                                                                 : retina::to_string(c.type);
            } catch (const Error&) {
                type = "unknown";
            }
        }
        nlohmann::ordered_json j;
        j["key"] = eye_key(f);
        j["type"] = type;
        j["file"] = f;
        std::fputs((j.dump() + "\n").c_str(), stdout);
    }
    std::fflush(stdout);
    if (std::ferror(stdout) != 0) throw OutputError("stdout", std::strerror(errno));
}

// `cohort-eye FILE -o OUTDIR`: the cohort's work for one input, in one worker process under
// the cohort's supervision (a crash or --eye-timeout-s is recorded as in a cohort run). A
// current record is kept (the resume rule). Exit 0: the eye's result is there; 1: its failure
// is recorded (or it is no export: the tables list it).
void run_eye(CohortOptions& o, const std::string& file, RunContext& ctx) {
    const Setup s = prepare(o);
    const fs::path out(o.out);
    const auto lock = open_output(out, /*exclusive=*/false, /*dirs=*/false, o.qc);
    std::vector<Skipped> skipped;
    const auto files = discover({file}, out, skipped);
    std::vector<Item> items;
    if (!files.empty()) {
        auto it = load_item(files.front(), out, o, s.sig, skipped);
        if (it) items.push_back(std::move(*it));
    }
    if (items.empty()) {
        for (const auto& k : skipped) {
            spdlog::warn("{}: {}", log_name(k.path), scrub(k.reason, absolute_path(k.path)));
        }
        if (skipped.empty()) spdlog::warn("{}: not a supported export, ignored", log_name(file));
        ctx.exit_code = static_cast<int>(ExitCode::kPartial);
        return;
    }
    Item& item = items.front();
    make_output_dirs(out, o.qc, item.key);
    if (!item.settled()) {
        run_workers(o, s.subjects, items, {0}, out, s.sig.failure, 1, lock->fd());
        if (::syncfs(lock->fd()) != 0) throw OutputError(out.string(), std::strerror(errno));
    } else {
        spdlog::info("eye {}: current {} kept", item.key, item.done ? "result" : "failure record");
    }
    if (!item.done) ctx.exit_code = static_cast<int>(ExitCode::kPartial);
}

// `cohort-tables DIR... -o OUTDIR`: the tables of a cohort whose eyes were analysed by
// `cohort-eye` jobs, from their records, with the code of `cohort`. Refuses (66) while an
// input has no current record.
void run_tables(CohortOptions& o, RunContext& ctx) {
    const Setup s = prepare(o);
    const fs::path out(o.out);
    const auto lock = open_output(out, /*exclusive=*/true, /*dirs=*/true, o.qc);
    std::vector<Skipped> skipped;
    const std::vector<Item> items = load_items(o, s, out, skipped);
    std::size_t missing = 0;
    const Item* first = nullptr;
    for (const auto& it : items) {
        if (it.settled()) continue;
        if (missing++ == 0) first = &it;
    }
    if (first != nullptr) {
        throw InputError(InputError::Kind::kMissing, (out / "eyes").string(),
                         fmt::format("no current result or failure record of {} input(s) "
                                     "(first: {}, eye {}): run `octshape cohort-eye` on them "
                                     "with the same options first",
                                     missing, first->path, first->key));
    }
    const CohortTables t = write_cohort_tables(out, items, skipped, s.groups, o.qc);
    if (t.failed > 0) ctx.exit_code = static_cast<int>(ExitCode::kPartial);
}

// The options every cohort command takes (the resume signature depends on them).
void add_cohort_options(CLI::App* cmd, CohortOptions& o) {
    cmd->add_option("-o,--output", o.out, "Output folder")->required();
    cmd->add_option("--groups", o.groups,
                    "Group column from a CSV with header subject_id,group, patient_id,group or "
                    "file,group (absolute path or file name); matching no eye is an error");
    cmd->add_option("--type", o.type,
                    "auto (decide from the BM segmentation: docs/cohort.md), macula or onh")
        ->check(CLI::IsMember({std::string("auto"), std::string(retina::to_string(retina::ScanType::kMacula)),
                               std::string(retina::to_string(retina::ScanType::kOnh))}))
        ->capture_default_str();
    cmd->add_flag("--qc", o.qc, "Write QC pictures OUTDIR/qc/<eye_key>_*.png");
    cmd->add_flag("--retry-failed", o.retry_failed,
                  "Redo inputs whose failure is recorded (by default a recorded failure of an "
                  "unchanged file with the same options is kept)");
    cmd->add_option("--eye-timeout-s", o.eye_timeout_s,
                    "Stop an eye still running after this many seconds and record it in "
                    "failures.csv (exit code 69); 0: no limit")
        ->capture_default_str();
    add_macula_analysis_options(cmd, o.eye, /*lateral_flag=*/false);
    add_onh_analysis_options(cmd, o.onh, /*per_eye_files=*/false);
    // One --no-lateral-registration for both analyses (the ONH options add it): the macula's
    // follows it once the command line is parsed.
    cmd->parse_complete_callback([&o] {
        o.eye.params.lateral_registration.enabled = o.onh.params.lateral_registration.enabled;
    });
    add_subject_options(cmd, o.subjects);
}

}  // namespace

void add_cohort_command(CLI::App& app, RunContext& ctx) {
    auto opts = std::make_shared<CohortOptions>();
    auto list_only = std::make_shared<bool>(false);
    CLI::App* cmd = app.add_subcommand(
        "cohort",
        "Analyse every supported export under the folders (recursive), N at a time in N worker "
        "processes (a crashed or hung eye is recorded, its worker replaced); resumable and crash "
        "safe. Writes OUTDIR/eyes/*.json, OUTDIR/eyes.csv, OUTDIR/failures.csv, and under "
        "OUTDIR/private/ all that names an input (paths; eye.key, the secret of the eye keys; the "
        "subject key it makes when no subject option is given): the rest can be handed over (docs/cohort.md). "
        "Exit 0: all eyes done; 1: some inputs failed (listed in failures.csv)");
    cmd->add_option("inputs", opts->inputs, "Folders (searched recursively) or files")
        ->required();
    // Given, it must be a count: --jobs 0 is a mistake, not "the default" (leave it out).
    cmd->add_option("-j,--jobs", opts->jobs, "Eyes analysed at once (default: one per core)")
        ->check(CLI::Validator(
            [](std::string& v) {
                return v.find_first_not_of("0123456789") == std::string::npos &&
                               v.find_first_not_of('0') != std::string::npos
                           ? std::string()
                           : "must be a count of 1 or more (leave it out for one per core), "
                             "not " + v;
            },
            "N >= 1"));
    cmd->add_flag("--list", *list_only,
                  "Analyse nothing: print one JSON line {key, type, file} per input the run "
                  "would analyse (type: macula, onh or unknown), for a workflow to plan its jobs");
    add_cohort_options(cmd, *opts);
    cmd->callback([opts, list_only, &ctx] {
        if (*list_only) {
            list(*opts);
        } else {
            run(*opts, ctx);
        }
    });

    auto eye_opts = std::make_shared<CohortOptions>();
    auto eye_file = std::make_shared<std::string>();
    CLI::App* eye = app.add_subcommand(
        "cohort-eye",
        "Do for ONE input what `octshape cohort` does for each (classify, analyse as macula or "
        "ONH in a supervised worker, or record the failure with its reason and exit code) in "
        "the same OUTDIR layout; one Snakemake/Slurm job per input (workflow/Snakefile, "
        "docs/cohort.md). Takes the cohort's options. Exit 0: the eye's result is written (or "
        "was current); 1: its failure is recorded");
    eye->add_option("file", *eye_file, "The input export")->required();
    add_cohort_options(eye, *eye_opts);
    eye->callback([eye_opts, eye_file, &ctx] { run_eye(*eye_opts, *eye_file, ctx); });

    auto tab_opts = std::make_shared<CohortOptions>();
    CLI::App* tables = app.add_subcommand(
        "cohort-tables",
        "Write OUTDIR/eyes.csv, eyes_onh.csv, failures.csv, private/inputs.csv and "
        "private/failures.csv (and with --qc the gallery) from the "
        "records `octshape cohort-eye` wrote for the inputs, with the cohort's code: the "
        "workflow's last job. Takes the cohort's inputs and options. Exit 0: all eyes done; 1: "
        "some inputs failed (in failures.csv); 66: an input has no current record yet");
    tables->add_option("inputs", tab_opts->inputs, "Folders (searched recursively) or files")
        ->required();
    add_cohort_options(tables, *tab_opts);
    tables->callback([tab_opts, &ctx] { run_tables(*tab_opts, ctx); });
}

}  // namespace octshape::app
