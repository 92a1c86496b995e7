// The per-eye unit of `octshape cohort`: resume check, analysis, failure record
// (docs/cohort.md, "Resume rule", "Which files, which analysis").

#include "commands/cohort_eye.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <new>

#include "commands/provenance.h"
#include "octshape/qc/names.h"
#include "octshape/error.h"
#include "octshape/io/atomic_file.h"
#include "octshape/io/scan_reader.h"
#include "octshape/io/sha256.h"
#include "octshape/retina/scan_type.h"

namespace octshape::app {

namespace fs = std::filesystem;
namespace record = retina::record;

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

fs::path make_private_dir(const fs::path& out) {
    const fs::path d = out / "private";
    std::error_code ec;
    fs::create_directories(d, ec);
    if (ec || !fs::is_directory(d)) {
        throw OutputError(d.string(), "cannot create directory: " + ec.message());
    }
    if (::chmod(d.c_str(), 0700) != 0) throw OutputError(d.string(), std::strerror(errno));
    return d;
}

namespace {

// OUTDIR/private/<name>: read when it exists, else made from RAND_bytes (mode 0600). Returns
// the key. `what` names its use in the log.
std::string own_key(const fs::path& private_dir, const char* name, const char* what) {
    const fs::path p = private_dir / name;
    std::error_code ec;
    if (fs::exists(p, ec)) {
        std::string key = read_key_file(p.string());
        spdlog::info("{}: HMAC under the key in {} (made by an earlier run)", what, p.string());
        return key;
    }
    const std::string key = io::random_hex(kKeyFileBytes);
    // Written under a name of this process, then linked into place: link() never replaces, so
    // of several jobs making the key at once the first one's is the key of all.
    const fs::path tmp = private_dir / fmt::format(".{}.tmp-{}", name, ::getpid());
    fs::remove(tmp, ec);
    const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0600);
    if (fd < 0) throw OutputError(tmp.string(), std::strerror(errno));
    const std::string line = key + "\n";
    const bool ok = ::write(fd, line.data(), line.size()) == static_cast<ssize_t>(line.size()) &&
                    ::fsync(fd) == 0;
    ::close(fd);
    const bool linked = ok && ::link(tmp.c_str(), p.c_str()) == 0;
    const bool lost_race = ok && !linked && errno == EEXIST;
    fs::remove(tmp, ec);
    if (lost_race) {
        spdlog::info("{}: HMAC under the key in {} (made by a job beside this one)", what,
                     p.string());
        return read_key_file(p.string());
    }
    if (!linked) throw OutputError(p.string(), std::string("cannot write the key ") + name);
    spdlog::info("{}: HMAC under a new random key in {} (keep it with the study's "
                 "identification list; later runs on this folder reuse it)",
                 what, p.string());
    return key;
}

}  // namespace

std::string own_subject_key(const fs::path& private_dir) {
    (void)own_key(private_dir, "subject.key", "subject ids");
    return (private_dir / "subject.key").string();
}

std::string own_eye_key(const fs::path& private_dir) {
    return own_key(private_dir, "eye.key", "eye keys");
}

SubjectOptions cohort_subject_options(const CohortOptions& o) {
    SubjectOptions so = o.subjects;
    if (so.key.empty() && so.key_file.empty() && so.map_file.empty() && so.mode.empty()) {
        so.key_file = own_subject_key(make_private_dir(o.out));
    }
    return so;
}

CohortSignatures cohort_signatures(const CohortOptions& o, const SubjectSource& subjects) {
    CohortSignatures s;
    s.macula = macula_options_text(o.eye) + " subjects=" + subjects.fingerprint();
    s.onh = onh_options_text(o.onh) + " subjects=" + subjects.fingerprint();
    s.failure = s.macula + " " + s.onh + " type=" + o.type + (o.qc ? " qc" : "") +
                fmt::format(" eye_timeout_s={:g}", o.eye_timeout_s);
    return s;
}

nlohmann::json slim(const nlohmann::json& j) {
    nlohmann::json s;
    for (const auto& k : retina::record::names(retina::record::slim_keys())) {
        if (j.contains(k)) s[k] = j[k];
    }
    return s;
}

fs::path eye_result_file(const fs::path& out, const std::string& key) {
    return out / "eyes" / (key + ".json");
}

fs::path eye_failure_file(const fs::path& out, const std::string& key) {
    return out / "failures" / (key + ".json");
}

std::optional<Item> load_item(const std::string& f, const fs::path& out, const CohortOptions& o,
                              const CohortSignatures& sig, std::vector<Skipped>& skipped) {
    Item it;
    it.path = f;
    it.key = eye_key(f);
    try {
        it.facts = file_facts(f);
    } catch (const InputError& e) {
        skipped.push_back({f, it.key, e.what(), static_cast<int>(e.exit_code())});
        return std::nullopt;
    }
    const fs::path eye_json = eye_result_file(out, it.key);
    const fs::path fail_json = eye_failure_file(out, it.key);
    std::error_code ec;
    if (fs::exists(eye_json, ec)) {
        try {
            nlohmann::json j = read_json_file(eye_json.string());
            const std::string& cohort = record::name(record::Name::kCohort);
            const std::string type =
                j.contains(cohort) && j[cohort].is_object()
                    ? j[cohort].value(record::name(record::Name::kScanType), std::string())
                    : std::string();
            // A record of no known type is checked for the macula's pictures (as before).
            const auto pictures = qc::picture_names(
                it.key, record::parse_scan_type(type).value_or(retina::ScanType::kMacula));
            const bool qc_ok = !o.qc || std::all_of(pictures.begin(), pictures.end(),
                                                    [&](const std::string& name) {
                                                        return fs::exists(out / "qc" / name, ec);
                                                    });
            const RecordState state =
                j.contains(cohort) ? record_state(j[cohort], it.facts,
                                                  sig.eye(record::parse_scan_type(type)))
                                   : RecordState::kFileChanged;
            if (state == RecordState::kCurrent && (o.type == "auto" || o.type == type) &&
                qc_ok) {
                it.done = true;
                it.slim = slim(j);
            } else if (state == RecordState::kFingerprintChanged) {
                it.refingerprinted = true;
            }
        } catch (const InputError& e) {
            spdlog::warn("{}: unusable previous result, redoing the eye: {}", f, e.what());
        }
    }
    if (!it.done && !o.retry_failed && fs::exists(fail_json, ec)) {
        try {
            nlohmann::json j = read_json_file(fail_json.string());
            const std::string& cohort = record::name(record::Name::kCohort);
            if (j.contains(cohort) && record_is_current(j[cohort], it.facts, sig.failure)) {
                it.failed = true;
                it.failure = j;
            }
        } catch (const InputError& e) {
            spdlog::warn("{}: unusable failure record, redoing the eye: {}", f, e.what());
        }
    }
    return it;
}

int analyse_eye(const CohortOptions& o, const SubjectSource& subjects, const Item& item,
                const fs::path& out, std::string& message) {
    try {
        const FileFacts facts = file_facts(item.path);
        Provenance read;
        // With --qc the macula's B-scan picture shows the pixels: read them now, so that the
        // file is read once (an ONH eye is read again below, with what its ILM source needs).
        io::ReadOptions read_options;
        read_options.pixels = o.qc;
        io::HashedScan input = io::read_scan_hashed(item.path, read_options);
        read.mark("read_hash");
        const io::Scan& scan = input.scan;
        retina::ScanType type = retina::ScanType::kMacula;
        std::string why = "--type macula";
        if (o.type == retina::to_string(retina::ScanType::kOnh)) {
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
            // Reads (and hashes) the file again, with the pixels the level set needs; the first
            // reading is freed before, so that the eye's peak memory stays that of one reading.
            input = io::HashedScan{};
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
            prepend_stages(r.json["provenance"], read);
        }
        // Atomic, not fsync'ed: the parent syncs the file system once before the tables.
        io::write_text_atomically(eye_result_file(out, item.key).string(),
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

void record_failure(Item& item, const fs::path& out, const std::string& options_text,
                    const std::string& reason, int exit_code) {
    nlohmann::ordered_json f;
    f[record::name(record::Name::kCohort)] = cohort_record(item.facts, options_text, std::nullopt);
    // The path is in OUTDIR/private/failures.csv.
    f[record::name(record::Name::kReason)] = scrub(reason, item.path);
    f[record::name(record::Name::kExitCode)] = exit_code;
    io::write_text_atomically(eye_failure_file(out, item.key).string(),
                              f.dump(2) + "\n", {.durable = false});
    item.failed = true;
    item.failure = f;
}

bool take_result(Item& item, const fs::path& out, std::string& reason) {
    try {
        item.slim = slim(read_json_file(eye_result_file(out, item.key).string()));
        item.done = true;
        std::error_code ec;
        fs::remove(eye_failure_file(out, item.key), ec);
        return true;
    } catch (const InputError& e) {
        reason = std::string("result unreadable: ") + e.what();
        return false;
    }
}

}  // namespace octshape::app
