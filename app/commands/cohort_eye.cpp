// The per-eye unit of `octshape cohort`: resume check, analysis, failure record
// (docs/cohort.md, "Resume rule", "Which files, which analysis").

#include "commands/cohort_eye.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <new>

#include "octshape/io/atomic_file.h"
#include "octshape/error.h"
#include "octshape/io/scan_reader.h"
#include "octshape/io/sha256.h"
#include "octshape/retina/scan_type.h"

namespace octshape::app {

namespace fs = std::filesystem;

std::string eye_key(const std::string& abs_path) {
    return io::sha256_hex(abs_path).substr(0, 16);
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
    for (const char* k : {"cohort", "input", "csv_row"}) {
        if (j.contains(k)) s[k] = j[k];
    }
    return s;
}

std::optional<Item> load_item(const std::string& f, const fs::path& out, const CohortOptions& o,
                              const CohortSignatures& sig, std::vector<Skipped>& skipped) {
    Item it;
    it.path = f;
    it.key = eye_key(f);
    try {
        it.facts = file_facts(f);
    } catch (const InputError& e) {
        skipped.push_back({f, e.what(), static_cast<int>(e.exit_code())});
        return std::nullopt;
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
            if (j.contains("cohort") && record_is_current(j["cohort"], it.facts, sig.eye(type)) &&
                (o.type == "auto" || o.type == type) && qc_ok) {
                it.done = true;
                it.slim = slim(j);
            }
        } catch (const InputError& e) {
            spdlog::warn("{}: unusable previous result, redoing the eye: {}", f, e.what());
        }
    }
    if (!it.done && !o.retry_failed && fs::exists(fail_json, ec)) {
        try {
            nlohmann::json j = read_json_file(fail_json.string());
            if (j.contains("cohort") && record_is_current(j["cohort"], it.facts, sig.failure)) {
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
        const io::HashedScan input = io::read_scan_hashed(item.path);
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

void record_failure(Item& item, const fs::path& out, const std::string& options_text,
                    const std::string& reason, int exit_code) {
    nlohmann::ordered_json f;
    f["cohort"] = cohort_record(item.facts, options_text, "unknown");
    f["reason"] = reason;
    f["exit_code"] = exit_code;
    io::write_text_atomically((out / "failures" / (item.key + ".json")).string(),
                              f.dump(2) + "\n", {.durable = false});
    item.failed = true;
    item.failure = f;
}

bool take_result(Item& item, const fs::path& out, std::string& reason) {
    try {
        item.slim = slim(read_json_file((out / "eyes" / (item.key + ".json")).string()));
        item.done = true;
        std::error_code ec;
        fs::remove(out / "failures" / (item.key + ".json"), ec);
        return true;
    } catch (const InputError& e) {
        reason = std::string("result unreadable: ") + e.what();
        return false;
    }
}

}  // namespace octshape::app
