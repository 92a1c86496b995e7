// `octshape cohort DIR... -o OUTDIR`: every supported export under the folders, macula or ONH
// by scan content, N eyes at a time in N worker processes; resumable and crash safe.
// Layout, resume rule and the crash-safety argument: docs/cohort.md.

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <sys/file.h>
#include <sys/prctl.h>
#include <sys/stat.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <spdlog/spdlog.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <chrono>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <map>
#include <memory>
#include <random>
#include <nlohmann/json.hpp>
#include <thread>

#include "commands/command.h"
#include "commands/eye_record.h"
#include "commands/gallery.h"
#include "commands/macula_eye.h"
#include "commands/onh_eye.h"
#include "commands/provenance.h"
#include "octshape/io/atomic_file.h"
#include "octshape/io/error.h"
#include "octshape/io/scan_reader.h"
#include "octshape/io/sha256.h"
#include "octshape/retina/report_util.h"
#include "octshape/retina/scan_type.h"

namespace octshape::app {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

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
    std::string key;   // eye key: first 16 hex digits of SHA-256(path)
    FileFacts facts;
    bool done = false;       // a current result exists
    bool failed = false;     // a current failure record exists
    nlohmann::json slim;     // what eyes.csv needs of the result
    nlohmann::json failure;  // the failure record
};

// Holds an exclusive lock on OUTDIR/.lock for the whole run (released by the kernel even on
// SIGKILL), so two runs never write the same OUTDIR.
class DirLock {
public:
    explicit DirLock(const fs::path& dir) {
        const fs::path p = dir / ".lock";
        fd_ = ::open(p.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
        if (fd_ < 0) throw OutputError(p.string(), std::strerror(errno));
        if (::flock(fd_, LOCK_EX | LOCK_NB) != 0) {
            ::close(fd_);
            throw UsageError("another `octshape cohort` is writing " + dir.string() +
                             " (lock " + p.string() + ")");
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

// OUTDIR/private/: everything that names an input (docs/cohort.md, "Output folder"); only its
// owner may read it.
fs::path make_private_dir(const fs::path& out) {
    const fs::path d = out / "private";
    make_dir(d);
    if (::chmod(d.c_str(), 0700) != 0) throw OutputError(d.string(), std::strerror(errno));
    return d;
}

// The subject key of a cohort run without a subject option: OUTDIR/private/subject.key, made
// (64 random hex digits, mode 0600) by the first run and reused by every later one.
std::string own_subject_key(const fs::path& private_dir) {
    const fs::path p = private_dir / "subject.key";
    std::error_code ec;
    if (fs::exists(p, ec)) {
        spdlog::info("subject ids: HMAC under the key in {} (made by an earlier run)", p.string());
        return p.string();
    }
    std::random_device rd;
    std::string key;
    for (int i = 0; i < 8; ++i) key += fmt::format("{:08x}", rd());
    const fs::path tmp = private_dir / ".subject.key.tmp";
    fs::remove(tmp, ec);
    const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0600);
    if (fd < 0) throw OutputError(tmp.string(), std::strerror(errno));
    const std::string line = key + "\n";
    const bool ok = ::write(fd, line.data(), line.size()) == static_cast<ssize_t>(line.size()) &&
                    ::fsync(fd) == 0;
    ::close(fd);
    if (!ok || ::rename(tmp.c_str(), p.c_str()) != 0) {
        fs::remove(tmp, ec);
        throw OutputError(p.string(), "cannot write the subject key");
    }
    spdlog::info("subject ids: HMAC under a new random key in {} (keep it with the study's "
                 "identification list; later runs on this folder reuse it)",
                 p.string());
    return p.string();
}

// A failure reason fit for OUTDIR/failures.csv: the input's path, file name, stem and folder
// name replaced by "<input>" (they are in OUTDIR/private/failures.csv).
std::string scrub(std::string reason, const std::string& abs_path) {
    const fs::path p(abs_path);
    for (const std::string& s : {abs_path, p.filename().string(), p.stem().string(),
                                 p.parent_path().filename().string()}) {
        if (s.size() < 3) continue;  // too short to be a name, and would mangle the reason
        for (std::size_t at = reason.find(s); at != std::string::npos;
             at = reason.find(s, at + 7)) {
            reason.replace(at, s.size(), "<input>");
        }
    }
    return reason;
}

// Temporary files of writes that a kill interrupted (".NAME.tmp-PID-RANDOM").
void remove_stale_temporaries(const fs::path& d) {
    std::error_code ec;
    for (fs::directory_iterator it(d, ec), end; !ec && it != end; it.increment(ec)) {
        const std::string name = it->path().filename().string();
        if (name.size() > 1 && name[0] == '.' && name.find(".tmp-") != std::string::npos) {
            std::error_code rm;
            fs::remove(it->path(), rm);
        }
    }
}

// A file that could not be taken in: path, reason, exit code.
struct Skipped {
    std::string path;
    std::string key;  // eye_key(path)
    std::string reason;
    int exit_code = 0;
};

bool has_export_extension(const fs::path& p) {
    std::string ext = p.extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(),
                   [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    return ext == ".vol" || ext == ".xml";
}

// Every regular file under the inputs whose content is a supported export, sorted, unique.
// A .vol/.xml file of unknown content and an unreadable file go to `skipped`; other files
// (TIFF B-scans of an XML export, notes, ...) are ignored.
std::vector<std::string> discover(const std::vector<std::string>& inputs, const fs::path& out,
                                  std::vector<Skipped>& skipped) {
    std::vector<std::string> files;
    const std::string out_abs = absolute_path(out.string());
    auto consider = [&](const fs::path& p) {
        const std::string abs = absolute_path(p.string());
        if (abs.rfind(out_abs + "/", 0) == 0) return;  // our own outputs
        try {
            if (io::detect_format(abs) != io::FileFormat::kUnknown) {
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
    return files;
}

// What eyes.csv needs of a per-eye JSON (the rest stays on disk).
nlohmann::json slim(const nlohmann::json& j) {
    nlohmann::json s;
    for (const char* k : {"cohort", "input", "csv_row"}) {
        if (j.contains(k)) s[k] = j[k];
    }
    return s;
}

std::string signal_name(int sig) {
    const char* d = ::strsignal(sig);
    return "signal " + std::to_string(sig) + (d != nullptr ? std::string(" (") + d + ")" : "");
}

// ---- The workers: eye after eye ----------------------------------------------------------

// A worker is a child process forked by the batch that analyses eye after eye: the parent sends
// it an eye's index, the worker writes the eye's JSON (atomically) and answers with an EyeDone
// record, then waits for the next index. Parent and worker talk over a SOCK_SEQPACKET socket
// pair: every message arrives whole, a worker's death reads as end-of-file, and a send to a dead
// peer fails with EPIPE instead of raising SIGPIPE (MSG_NOSIGNAL). Supervision: docs/cohort.md.
struct EyeDone {
    std::uint64_t index = 0;  // the eye's index in the batch's item list
    std::int32_t code = 0;    // 0: the eye's JSON is written; else the exit code of the failure
    std::uint32_t length = 0;  // bytes of the failure message that follow
};
constexpr std::size_t kMaxMessage = 4000;  // a failure message is cut to this many bytes

// One eye: returns 0 when its JSON is written, else the failure's exit code and `message`.
int analyse_eye(const CohortOptions& o, const SubjectSource& subjects, const Item& item,
                const fs::path& out, std::string& message) {
    try {
        const FileFacts facts = file_facts(item.path);
        Provenance read;
        const io::HashedScan input = io::read_scan_hashed(item.path);
        read.mark("read_hash");
        const io::Scan& scan = input.scan;
        retina::ScanType type = retina::ScanType::kMacula;
        std::string why = "--type macula";
        if (o.type == "onh") {
            type = retina::ScanType::kOnh;
            why = "--type onh";
        } else if (o.type == "auto") {
            const auto c = retina::classify_scan(scan);
            type = c.type;
            why = c.reason;
        }
        if (type == retina::ScanType::kUnsupported) throw AnalysisError("not analysable: " + why);
        EyeResult r;
        if (type == retina::ScanType::kOnh) {
            OnhEyeOptions eo = o.onh;
            if (o.qc) {
                eo.qc_dir = (out / "qc").string();
                eo.qc_stem = item.key;
            }
            // Reads (and hashes) the file again, with the pixels the level set needs.
            r = analyse_onh_eye(item.path, facts, eo, subjects);
        } else {
            MaculaEyeOptions eo = o.eye;
            eo.check_scan_type = false;  // decided above
            if (o.qc) {
                eo.qc_dir = (out / "qc").string();
                eo.qc_stem = item.key;
            }
            r = analyse_macula_eye(item.path, facts, input, eo, subjects);
            // The first reading's time and the run's start, before the analysis's stages.
            nlohmann::ordered_json p = read.json();
            for (const auto& [k, v] : r.json["provenance"]["seconds"].items()) {
                p["seconds"][k] = v;
            }
            r.json["provenance"] = p;
        }
        // Atomic, not fsync'ed: the parent syncs the file system once before the tables.
        io::write_text_atomically((out / "eyes" / (item.key + ".json")).string(),
                                  r.json.dump(2) + "\n", {.durable = false});
        return 0;
    } catch (const Error& e) {
        message = e.what();
        return static_cast<int>(e.exit_code());
    } catch (const std::bad_alloc&) {
        message = "out of memory";
        return static_cast<int>(ExitCode::kInternal);
    } catch (const std::exception& e) {
        message = std::string("internal error: ") + e.what();
        return static_cast<int>(ExitCode::kInternal);
    }
}

// The worker's life: eye after eye until the parent closes its end of the socket.
[[noreturn]] void worker_main(const CohortOptions& o, const SubjectSource& subjects,
                              const std::vector<Item>& items, const fs::path& out, int sock) {
    for (;;) {
        std::uint64_t index = 0;
        const auto n = ::recv(sock, &index, sizeof index, 0);
        if (n < 0 && errno == EINTR) continue;
        if (n != static_cast<ssize_t>(sizeof index) || index >= items.size()) break;
        std::string message;
        const int code = analyse_eye(o, subjects, items[index], out, message);
        if (message.size() > kMaxMessage) message.resize(kMaxMessage);
        EyeDone done;
        done.index = index;
        done.code = code;
        done.length = static_cast<std::uint32_t>(message.size());
        std::string record(sizeof done, '\0');
        std::memcpy(record.data(), &done, sizeof done);
        record += message;
        spdlog::default_logger()->flush();
        // A failed send means the parent is gone (and this worker with it: PR_SET_PDEATHSIG).
        if (::send(sock, record.data(), record.size(), MSG_NOSIGNAL) < 0) break;
    }
    spdlog::default_logger()->flush();
    ::_exit(0);
}

// ---- The parent: scheduling, progress, records -------------------------------------------

class Progress {
public:
    Progress(std::size_t total, std::size_t pending, bool bar)
        : total_(total), pending_(pending), bar_(bar), start_(Clock::now()) {}

    void finished(const Item& item, bool ok, const std::string& reason, double seconds) {
        ++done_;
        if (!ok) ++failed_;
        if (bar_) {
            if (!ok) {
                clear();
                spdlog::warn("{}: {}", item.path, reason);
            }
            draw();
        } else if (ok) {
            spdlog::info("[{}/{}] {} ({:.1f} s)", done_, pending_, item.path, seconds);
        } else {
            spdlog::warn("[{}/{}] {}: FAILED: {}", done_, pending_, item.path, reason);
        }
    }
    void end() {
        if (bar_ && pending_ > 0) {
            draw();
            std::fputc('\n', stderr);
        }
    }
    void draw() const {
        if (!bar_) return;
        const double t = std::chrono::duration<double>(Clock::now() - start_).count();
        const double rate = t > 0 ? static_cast<double>(done_) / t : 0.0;
        constexpr int kWidth = 30;
        const int fill = pending_ == 0 ? kWidth
                                    : static_cast<int>(kWidth * static_cast<double>(done_) /
                                                       static_cast<double>(pending_));
        std::string bar(static_cast<std::size_t>(fill), '#');
        bar.resize(kWidth, '.');
        std::string eta = "--";
        if (rate > 0) {
            const auto s = static_cast<long>(static_cast<double>(pending_ - done_) / rate);
            eta = fmt::format("{}:{:02}:{:02}", s / 3600, (s / 60) % 60, s % 60);
        }
        std::fprintf(stderr, "\r[%s] %zu/%zu files  %.2f files/s  ETA %s  failed %zu   ",
                     bar.c_str(), done_, pending_, rate, eta.c_str(), failed_);
        std::fflush(stderr);
    }

private:
    void clear() const { std::fprintf(stderr, "\r%80s\r", ""); }
    std::size_t total_;
    std::size_t pending_;
    bool bar_;
    Clock::time_point start_;
    std::size_t done_ = 0;
    std::size_t failed_ = 0;
};

// The parent's view of one worker process.
struct Worker {
    pid_t pid = -1;  // -1: no worker in this slot
    int sock = -1;   // the parent's end of the worker's socket pair
    bool busy = false;
    std::size_t index = 0;        // the eye in progress (when busy)
    Clock::time_point start = {};  // when that eye was sent
};

void record_failure(Item& item, const fs::path& out, const std::string& options_text,
                    const std::string& reason, int exit_code) {
    nlohmann::ordered_json f;
    f["cohort"] = cohort_record(item.facts, options_text, "unknown");
    f["reason"] = scrub(reason, item.path);  // the path is in OUTDIR/private/failures.csv
    f["exit_code"] = exit_code;
    io::write_text_atomically((out / "failures" / (item.key + ".json")).string(),
                              f.dump(2) + "\n", {.durable = false});
    item.failed = true;
    item.failure = f;
}

// OUTDIR/failures.csv (`with_paths` false: eye_key,reason,exit_code, reasons without the
// input's name) or OUTDIR/private/failures.csv (eye_key,file,reason,exit_code), by eye key.
std::string failures_csv(const std::vector<Item>& items, const std::vector<Skipped>& skipped,
                         bool with_paths) {
    std::vector<std::vector<std::string>> rows;
    const auto add = [&](const std::string& key, const std::string& path,
                         const std::string& reason, int code) {
        std::vector<std::string> r{key, scrub(reason, path), std::to_string(code)};
        if (with_paths) r.insert(r.begin() + 1, path);
        rows.push_back(std::move(r));
    };
    for (const auto& it : items) {
        if (!it.failed) continue;
        add(it.key, it.path, it.failure.value("reason", std::string()),
            it.failure.value("exit_code", 0));
    }
    for (const auto& s : skipped) add(s.key, s.path, s.reason, s.exit_code);
    std::sort(rows.begin(), rows.end());
    std::string s = retina::csv_line(
        with_paths ? std::vector<std::string>{"eye_key", "file", "reason", "exit_code"}
                   : std::vector<std::string>{"eye_key", "reason", "exit_code"});
    for (const auto& r : rows) s += retina::csv_line(r);
    return s;
}

// OUTDIR/private/inputs.csv: eye_key,file,sha256,result (eye | failure) of this run's inputs,
// by eye key: the only map from the keys of the shared tables back to the files.
std::string inputs_csv(const std::vector<Item>& items, const std::vector<Skipped>& skipped) {
    std::vector<std::vector<std::string>> rows;
    for (const auto& it : items) {
        std::string sha;
        if (it.done && it.slim.contains("input") && it.slim["input"].is_object()) {
            sha = it.slim["input"].value("sha256", std::string());
        }
        rows.push_back({it.key, it.path, sha, it.done ? "eye" : (it.failed ? "failure" : "")});
    }
    for (const auto& s : skipped) rows.push_back({s.key, s.path, "", "failure"});
    std::sort(rows.begin(), rows.end());
    std::string s = retina::csv_line({"eye_key", "file", "sha256", "result"});
    for (const auto& r : rows) s += retina::csv_line(r);
    return s;
}

void run(CohortOptions& o, RunContext& ctx) {
    if (o.type != "auto" && o.type != "macula" && o.type != "onh") {
        throw UsageError("--type must be auto, macula or onh");
    }
    if (o.jobs < 0) throw UsageError("--jobs must be >= 1");
    if (!(o.eye_timeout_s >= 0.0)) throw UsageError("--eye-timeout-s must be >= 0");
    const int cores = static_cast<int>(std::thread::hardware_concurrency());
    const int jobs = o.jobs > 0 ? o.jobs : std::max(1, cores);
    o.eye.params.tau_mm = o.eye.tau_um * 1e-3;
    o.eye.params.validate();
    for (const auto& in : o.inputs) {  // before anything is written
        std::error_code ec;
        if (!fs::exists(in, ec)) throw InputError::missing(in);
    }
    io::check_output_directory(o.out);
    const fs::path out(o.out);
    make_dir(out);
    const DirLock lock(out);
    for (const char* d : {"eyes", "failures"}) make_dir(out / d);
    if (o.qc) make_dir(out / "qc");
    const fs::path private_dir = make_private_dir(out);
    // Without a subject option the cohort keys the pseudonyms with its own random key.
    SubjectOptions subject_options = o.subjects;
    if (subject_options.key.empty() && subject_options.key_file.empty() &&
        subject_options.map_file.empty() && subject_options.mode.empty()) {
        subject_options.key_file = own_subject_key(private_dir);
    }
    const SubjectSource subjects = SubjectSource::from_options(subject_options);
    GroupMap groups;
    if (!o.groups.empty()) groups = GroupMap::load(o.groups, subjects);
    for (const auto& d : {out, out / "eyes", out / "failures", out / "qc", private_dir}) {
        remove_stale_temporaries(d);
    }

    // The eye record's options, and the failure record's (which also depend on --type).
    // The options an eye's record must carry to count as done, per scan type (changing an ONH
    // option redoes the ONH eyes only).
    const std::string macula_options =
        macula_options_text(o.eye) + " subjects=" + subjects.fingerprint();
    const std::string onh_options = onh_options_text(o.onh) + " subjects=" + subjects.fingerprint();
    const auto eye_options_of = [&](const std::string& type) -> const std::string& {
        return type == "onh" ? onh_options : macula_options;
    };
    const std::string fail_options = macula_options + " " + onh_options + " type=" + o.type +
                                     (o.qc ? " qc" : "") +
                                     fmt::format(" eye_timeout_s={:g}", o.eye_timeout_s);

    std::vector<Skipped> skipped;
    const auto files = discover(o.inputs, out, skipped);
    std::size_t refingerprinted = 0;  // results made by other code or parameters
    std::vector<Item> items;
    items.reserve(files.size());
    std::vector<std::size_t> pending;
    for (const auto& f : files) {
        Item it;
        it.path = f;
        it.key = eye_key(f);
        try {
            it.facts = file_facts(f);
        } catch (const InputError& e) {
            skipped.push_back({f, it.key, e.what(), static_cast<int>(e.exit_code())});
            continue;
        }
        const fs::path eye_json = out / "eyes" / (it.key + ".json");
        const fs::path fail_json = out / "failures" / (it.key + ".json");
        std::error_code ec;
        if (fs::exists(eye_json, ec)) {
            try {
                nlohmann::json j = read_json_file(eye_json.string());
                const std::string type = j.contains("cohort")
                                             ? j["cohort"].value("scan_type", std::string())
                                             : std::string();
                const char* picture = type == "onh" ? "_enface.png" : "_thickness.png";
                const bool qc_ok = !o.qc || fs::exists(out / "qc" / (it.key + picture));
                const RecordState state = j.contains("cohort")
                                              ? record_state(j["cohort"], it.facts,
                                                             eye_options_of(type))
                                              : RecordState::kFileChanged;
                if (state == RecordState::kCurrent && (o.type == "auto" || o.type == type) &&
                    qc_ok) {
                    it.done = true;
                    it.slim = slim(j);
                } else if (state == RecordState::kFingerprintChanged) {
                    ++refingerprinted;
                }
            } catch (const InputError& e) {
                spdlog::warn("{}: unusable previous result, redoing the eye: {}", f, e.what());
            }
        }
        if (!it.done && !o.retry_failed && fs::exists(fail_json, ec)) {
            try {
                nlohmann::json j = read_json_file(fail_json.string());
                if (j.contains("cohort") &&
                    record_is_current(j["cohort"], it.facts, fail_options)) {
                    it.failed = true;
                    it.failure = j;
                }
            } catch (const InputError& e) {
                spdlog::warn("{}: unusable failure record, redoing the eye: {}", f, e.what());
            }
        }
        if (!it.done && !it.failed) pending.push_back(items.size());
        items.push_back(std::move(it));
    }
    const std::size_t resumed = items.size() - pending.size();
    spdlog::info("{} exports found, {} already done (results or recorded failures), {} to do, "
                 "{} job(s)",
                 items.size(), resumed, pending.size(), jobs);
    if (refingerprinted > 0) {
        spdlog::info("{} eye(s) redone: their results were made by other code or parameters "
                     "(fingerprint differs from this binary's {})",
                     refingerprinted, version_text());
    }

    const bool bar = ::isatty(STDERR_FILENO) != 0 && spdlog::get_level() <= spdlog::level::info;
    Progress progress(items.size(), pending.size(), bar);
    progress.draw();
    // The eyes run in `jobs` worker processes, each forked once and given eye after eye; a
    // worker that dies mid-eye (crash) or is killed (--eye-timeout-s) has its eye recorded as a
    // failure and is replaced. Supervision: docs/cohort.md.
    std::vector<Worker> workers(std::min(pending.size(), static_cast<std::size_t>(jobs)));
    std::vector<pid_t> retired;  // workers told to stop, or killed; reaped before the tables
    std::size_t next = 0;
    const pid_t parent = ::getpid();
    const auto worker_level =
        spdlog::get_level() <= spdlog::level::debug ? spdlog::get_level() : spdlog::level::err;
    const auto start_worker = [&](Worker& w) {
        int sv[2];
        if (::socketpair(AF_UNIX, SOCK_SEQPACKET | SOCK_CLOEXEC, 0, sv) != 0) {
            throw OutputError("socketpair", std::strerror(errno));
        }
        std::fflush(stderr);
        spdlog::default_logger()->flush();
        const pid_t pid = ::fork();
        if (pid < 0) throw OutputError("fork", std::strerror(errno));
        if (pid == 0) {
            // The worker dies with the parent (SIGKILL of the batch kills its eyes too).
            ::prctl(PR_SET_PDEATHSIG, SIGKILL);
            if (::getppid() != parent) ::_exit(static_cast<int>(ExitCode::kInternal));
            ::close(sv[0]);
            // The other workers' sockets: each must see end-of-file when the parent closes it.
            for (const Worker& other : workers) {
                if (other.sock >= 0) ::close(other.sock);
            }
            // The lock is the batch's: an eye outliving a killed batch must not block the
            // re-run (its atomic write of the same result is harmless).
            ::close(lock.fd());
            spdlog::set_level(worker_level);
            worker_main(o, subjects, items, out, sv[1]);
        }
        ::close(sv[1]);
        w = Worker{};
        w.pid = pid;
        w.sock = sv[0];
    };
    // Gives an idle worker the next eye, or tells it to stop (closes its socket) if none is left.
    const auto dispatch = [&](Worker& w) {
        if (next >= pending.size()) {
            ::close(w.sock);
            retired.push_back(w.pid);
            w = Worker{};
            return;
        }
        const std::uint64_t index = pending[next++];
        if (::send(w.sock, &index, sizeof index, MSG_NOSIGNAL) !=
            static_cast<ssize_t>(sizeof index)) {
            --next;  // the worker died while idle: the eye stays pending, poll sees the end
            return;
        }
        w.busy = true;
        w.index = index;
        w.start = Clock::now();
    };
    const auto replace = [&](Worker& w) {
        w = Worker{};
        if (next < pending.size()) {
            start_worker(w);
            dispatch(w);
        }
    };
    const auto eye_failed = [&](std::size_t index, const std::string& reason, int code,
                                double secs) {
        record_failure(items[index], out, fail_options, reason, code);
        progress.finished(items[index], false, reason, secs);
    };
    const auto eye_done = [&](std::size_t index, double secs) {
        Item& item = items[index];
        try {
            item.slim = slim(read_json_file((out / "eyes" / (item.key + ".json")).string()));
            item.done = true;
            std::error_code ec;
            fs::remove(out / "failures" / (item.key + ".json"), ec);
            progress.finished(item, true, "", secs);
        } catch (const InputError& e) {
            eye_failed(index, std::string("result unreadable: ") + e.what(),
                       static_cast<int>(ExitCode::kInternal), secs);
        }
    };
    for (Worker& w : workers) {
        start_worker(w);
        dispatch(w);
    }
    std::vector<pollfd> fds;
    std::vector<Worker*> polled;
    for (;;) {
        fds.clear();
        polled.clear();
        int wait_ms = 1000;  // a bound, should an end go unnoticed by poll
        const auto now = Clock::now();
        for (Worker& w : workers) {
            if (w.pid < 0) continue;
            fds.push_back({w.sock, POLLIN, 0});
            polled.push_back(&w);
            if (w.busy && o.eye_timeout_s > 0.0) {
                const double left =
                    o.eye_timeout_s - std::chrono::duration<double>(now - w.start).count();
                wait_ms = std::clamp(static_cast<int>(std::ceil(left * 1000.0)), 0, wait_ms);
            }
        }
        if (fds.empty()) break;
        if (::poll(fds.data(), fds.size(), wait_ms) < 0 && errno != EINTR) {
            throw std::runtime_error(std::string("poll: ") + std::strerror(errno));
        }
        for (std::size_t k = 0; k < fds.size(); ++k) {
            if (fds[k].revents == 0) continue;
            Worker& w = *polled[k];
            std::array<char, sizeof(EyeDone) + kMaxMessage> buf{};
            const auto got = ::recv(w.sock, buf.data(), buf.size(), MSG_DONTWAIT);
            if (got < 0 && (errno == EINTR || errno == EAGAIN)) continue;
            const double secs =
                w.busy ? std::chrono::duration<double>(Clock::now() - w.start).count() : 0.0;
            if (got >= static_cast<ssize_t>(sizeof(EyeDone))) {
                EyeDone d;
                std::memcpy(&d, buf.data(), sizeof d);
                if (w.busy && d.index == w.index) {
                    w.busy = false;
                    const auto length = std::min<std::size_t>(
                        d.length, static_cast<std::size_t>(got) - sizeof d);
                    std::string message(buf.data() + sizeof d, length);
                    if (d.code == 0) {
                        eye_done(d.index, secs);
                    } else {
                        eye_failed(d.index,
                                   message.empty() ? "failed without a message" : message,
                                   d.code, secs);
                    }
                }
                dispatch(w);
                continue;
            }
            // End of file: the worker has ended (a short record cannot come from a worker; one
            // that sent it is stopped).
            if (got != 0) ::kill(w.pid, SIGKILL);
            ::close(w.sock);
            int status = 0;
            while (::waitpid(w.pid, &status, 0) < 0 && errno == EINTR) {
            }
            if (w.busy) {
                if (WIFSIGNALED(status)) {
                    eye_failed(w.index, "the analysis crashed: " + signal_name(WTERMSIG(status)),
                               static_cast<int>(ExitCode::kInternal), secs);
                } else {
                    const int code = WIFEXITED(status) ? WEXITSTATUS(status) : 0;
                    eye_failed(w.index,
                               fmt::format("failed without a message (the worker exited with "
                                           "status {} during the analysis)",
                                           code),
                               code != 0 ? code : static_cast<int>(ExitCode::kInternal), secs);
                }
            }
            replace(w);
        }
        // Eyes over the limit: the worker is killed (reaped before the tables) and replaced.
        for (Worker& w : workers) {
            if (w.pid < 0 || !w.busy || o.eye_timeout_s <= 0.0) continue;
            const double secs = std::chrono::duration<double>(Clock::now() - w.start).count();
            if (secs < o.eye_timeout_s) continue;
            ::kill(w.pid, SIGKILL);
            ::close(w.sock);
            retired.push_back(w.pid);
            eye_failed(w.index,
                       fmt::format("the analysis did not finish within --eye-timeout-s {:g} s "
                                   "and was stopped",
                                   o.eye_timeout_s),
                       static_cast<int>(ExitCode::kAnalysisFailed), secs);
            replace(w);
        }
    }
    for (const pid_t pid : retired) {
        while (::waitpid(pid, nullptr, 0) < 0 && errno == EINTR) {
        }
    }
    progress.end();

    // Every record of this run reaches the disk before the tables that list them (one syncfs
    // instead of two fsyncs per eye); the tables are rebuilt from the records of this run's
    // inputs, each written atomically and durably.
    if (::syncfs(lock.fd()) != 0) throw OutputError(out.string(), std::strerror(errno));
    std::vector<nlohmann::json> eyes;
    std::vector<std::string> names;
    std::size_t failed = skipped.size();
    for (const auto& it : items) {
        if (it.done) {
            eyes.push_back(it.slim);
            names.push_back((out / "eyes" / (it.key + ".json")).string());
        }
        if (it.failed) ++failed;
    }
    if (groups.by_file()) {
        std::map<std::string, std::string> paths;
        for (const auto& it : items) paths[it.key] = it.path;
        groups.set_paths(std::move(paths));
    }
    // One table per scan type (their parameter columns differ): eyes.csv holds the maculae,
    // eyes_onh.csv the optic nerve heads (written when the cohort has any).
    const std::string macula_table = eyes_csv(eyes, names, "macula", groups);
    const bool any_onh = std::any_of(eyes.begin(), eyes.end(), [](const nlohmann::json& e) {
        return e.contains("cohort") && e["cohort"].value("scan_type", std::string()) == "onh";
    });
    const std::string onh_table = any_onh ? eyes_csv(eyes, names, "onh", groups) : "";
    groups.check_matches();  // before any table is written
    io::write_text_atomically((out / "eyes.csv").string(), macula_table);
    if (any_onh) io::write_text_atomically((out / "eyes_onh.csv").string(), onh_table);
    io::write_text_atomically((out / "failures.csv").string(),
                              failures_csv(items, skipped, false));
    io::write_text_atomically((private_dir / "failures.csv").string(),
                              failures_csv(items, skipped, true));
    io::write_text_atomically((private_dir / "inputs.csv").string(), inputs_csv(items, skipped));
    spdlog::info("{} eyes in {}, {} failed (see {})", eyes.size(), (out / "eyes.csv").string(),
                 failed, (out / "failures.csv").string());
    if (o.qc) {
        const GalleryResult g = write_qc_gallery(out);
        spdlog::info("QC gallery: {} ({} eyes, {} failures, {} pictures)",
                     (out / "qc" / "index.html").string(), g.eyes, g.failures, g.pictures);
    }
    if (failed > 0) ctx.exit_code = static_cast<int>(ExitCode::kPartial);
}

}  // namespace

void add_cohort_command(CLI::App& app, RunContext& ctx) {
    auto opts = std::make_shared<CohortOptions>();
    CLI::App* cmd = app.add_subcommand(
        "cohort",
        "Analyse every supported export under the folders (recursive), N at a time in N worker "
        "processes (a crashed or hung eye is recorded, its worker replaced); resumable and crash "
        "safe. Writes OUTDIR/eyes/*.json, OUTDIR/eyes.csv, OUTDIR/failures.csv, and under "
        "OUTDIR/private/ all that names an input (paths; the subject key it makes when no subject "
        "option is given): the rest can be handed over (docs/cohort.md). "
        "Exit 0: all eyes done; 1: some inputs failed (listed in failures.csv)");
    cmd->add_option("inputs", opts->inputs, "Folders (searched recursively) or files")
        ->required();
    cmd->add_option("-o,--output", opts->out, "Output folder")->required();
    cmd->add_option("-j,--jobs", opts->jobs, "Eyes analysed at once (default: one per core)");
    cmd->add_option("--groups", opts->groups,
                    "Group column from a CSV with header subject_id,group, patient_id,group or "
                    "file,group (absolute path or file name); matching no eye is an error");
    cmd->add_option("--type", opts->type,
                    "auto (decide from the BM segmentation: docs/cohort.md), macula or onh")
        ->capture_default_str();
    cmd->add_flag("--qc", opts->qc, "Write QC pictures OUTDIR/qc/<eye_key>_*.png");
    cmd->add_flag("--retry-failed", opts->retry_failed,
                  "Redo inputs whose failure is recorded (by default a recorded failure of an "
                  "unchanged file with the same options is kept)");
    cmd->add_option("--eye-timeout-s", opts->eye_timeout_s,
                    "Stop an eye still running after this many seconds and record it in "
                    "failures.csv (exit code 69); 0: no limit")
        ->capture_default_str();
    add_macula_analysis_options(cmd, opts->eye);
    add_onh_analysis_options(cmd, opts->onh, /*per_eye_files=*/false);
    add_subject_options(cmd, opts->subjects);
    cmd->callback([opts, &ctx] { run(*opts, ctx); });
}

}  // namespace octshape::app
