#include "commands/eye_record.h"

#include <CLI/CLI.hpp>
#include <spdlog/spdlog.h>
#include <sys/stat.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <sstream>

#include "commands/provenance.h"
#include "octshape/error.h"
#include "octshape/io/csv.h"
#include "octshape/io/sha256.h"
#include "octshape/retina/cube_report.h"
#include "octshape/retina/etdrs.h"
#include "octshape/retina/onh_report.h"
#include "octshape/retina/record.h"
#include "octshape/version.h"

namespace octshape::app {
namespace {

namespace fs = std::filesystem;

std::string trim(const std::string& s) {
    const auto b = s.find_first_not_of(" \t\r\n");
    if (b == std::string::npos) return "";
    const auto e = s.find_last_not_of(" \t\r\n");
    return s.substr(b, e - b + 1);
}

// A small hand-written table (a subject or groups map, the private inputs table): io::read_csv,
// with the spaces around each field and header name dropped (written by hand, "file, group"
// means the column "group").
io::CsvTable read_small_table(const std::string& path) {
    io::CsvTable t = io::read_csv_file(path);
    for (auto& h : t.header) h = trim(h);
    for (auto& row : t.rows) {
        for (auto& f : row) f = trim(f);
    }
    return t;
}

std::string slurp_input(const std::string& path) {
    std::error_code ec;
    if (!fs::exists(path, ec)) throw InputError::missing(path);
    if (!fs::is_regular_file(path, ec)) throw InputError::not_regular(path);
    std::ifstream in(path, std::ios::binary);
    if (!in) throw InputError::unreadable(path, std::strerror(errno));
    std::ostringstream ss;
    ss << in.rdbuf();
    if (in.bad()) throw InputError::unreadable(path, "read failed");
    return ss.str();
}

// A two-column map file: returns (first header name, rows).
std::pair<std::string, std::vector<std::pair<std::string, std::string>>> read_map(
    const std::string& path, const std::string& value_column,
    const std::vector<std::string>& key_columns) {
    const io::CsvTable t = read_small_table(path);
    const auto& h = t.header;
    if (h.size() != 2 || h[1] != value_column ||
        std::find(key_columns.begin(), key_columns.end(), h[0]) == key_columns.end()) {
        std::string expected;
        for (const auto& k : key_columns) {
            expected += (expected.empty() ? "" : " or ") + k + "," + value_column;
        }
        throw InputError::corrupt(path, "header must be " + expected);
    }
    std::vector<std::pair<std::string, std::string>> rows;
    for (std::size_t i = 0; i < t.rows.size(); ++i) {
        if (t.rows[i][0].empty()) {
            throw InputError::corrupt(path, "row " + std::to_string(i + 1) +
                                                ": the first field is empty");
        }
        rows.emplace_back(t.rows[i][0], t.rows[i][1]);
    }
    return {h[0], rows};
}

std::string str_or_na(const nlohmann::json& j) {
    if (j.is_string()) return j.get<std::string>();
    if (j.is_number_integer()) return j.dump();
    return "NA";
}

}  // namespace

// ---- Subject pseudonyms -------------------------------------------------------------------

void add_subject_options(CLI::App* cmd, SubjectOptions& o) {
    cmd->add_option("--subject-key", o.key,
                    "Subject id = HMAC-SHA256(KEY, patient ID), 16 hex digits (a pseudonym "
                    "that clusters a person's eyes and visits). Visible to other users in `ps`: "
                    "prefer --subject-key-file");
    cmd->add_option("--subject-key-file", o.key_file,
                    "As --subject-key, the key being the first line of this file");
    cmd->add_option("--subjects", o.map_file,
                    "Subject ids from a CSV with header file,subject_id (absolute path or file "
                    "name) or patient_id,subject_id");
    cmd->add_option("--subject-id", o.mode,
                    "'raw': use the export's patient ID itself as subject id (identifying: only "
                    "when you explicitly want it)");
}

SubjectSource SubjectSource::from_options(const SubjectOptions& o) {
    const int given = static_cast<int>(!o.key.empty()) + static_cast<int>(!o.key_file.empty()) +
                      static_cast<int>(!o.map_file.empty()) + static_cast<int>(!o.mode.empty());
    if (given > 1) {
        throw UsageError(
            "give at most one of --subject-key, --subject-key-file, --subjects, --subject-id");
    }
    SubjectSource s;
    if (!o.mode.empty()) {
        if (o.mode != "raw") throw UsageError("--subject-id: only 'raw' is accepted");
        s.kind_ = Kind::kRaw;
        s.fingerprint_ = "raw";
        return s;
    }
    if (!o.key.empty() || !o.key_file.empty()) {
        std::string key = o.key;
        if (!o.key_file.empty()) {
            std::istringstream in(slurp_input(o.key_file));
            std::getline(in, key);
            key = trim(key);
        }
        if (key.empty()) throw UsageError("--subject-key/--subject-key-file: the key is empty");
        s.kind_ = Kind::kKeyedHash;
        s.key_ = key;
        // Reveals nothing of the key, but changes when it changes.
        s.fingerprint_ =
            "hmac:" + io::hmac_sha256_hex(key, "octshape subject key check").substr(0, 16);
        return s;
    }
    if (!o.map_file.empty()) {
        const auto [key_name, rows] =
            read_map(o.map_file, "subject_id", {"file", "patient_id"});
        s.kind_ = Kind::kMap;
        auto& target = key_name == "file" ? s.by_file_ : s.by_patient_;
        std::string all;
        for (const auto& [k, v] : rows) {
            target[k] = v;
            all += k + '\x1f' + v + '\x1e';
        }
        s.fingerprint_ = "map:" + key_name + ":" + io::sha256_hex(all).substr(0, 16);
        return s;
    }
    return s;
}

std::optional<std::string> SubjectSource::subject_id(const io::Scan& scan,
                                                     const std::string& file) const {
    switch (kind_) {
        case Kind::kNone:
            return std::nullopt;
        case Kind::kRaw: {
            const std::string p = patient_key(scan);
            if (p.empty()) return std::nullopt;
            return p;
        }
        case Kind::kKeyedHash: {
            const std::string p = patient_key(scan);
            if (p.empty()) return std::nullopt;
            return io::hmac_sha256_hex(key_, p).substr(0, kSubjectHexChars);
        }
        case Kind::kMap: {
            if (!by_file_.empty() || by_patient_.empty()) {
                if (auto it = by_file_.find(file); it != by_file_.end()) return it->second;
                const std::string name = fs::path(file).filename().string();
                if (auto it = by_file_.find(name); it != by_file_.end()) return it->second;
                return std::nullopt;
            }
            if (auto it = by_patient_.find(patient_key(scan)); it != by_patient_.end()) {
                return it->second;
            }
            return std::nullopt;
        }
    }
    return std::nullopt;
}

std::optional<std::string> SubjectSource::of_patient(const std::string& patient_id) const {
    const std::string p = trim(patient_id);
    switch (kind_) {
        case Kind::kNone:
            return std::nullopt;
        case Kind::kRaw:
            if (p.empty()) return std::nullopt;
            return p;
        case Kind::kKeyedHash:
            if (p.empty()) return std::nullopt;
            return io::hmac_sha256_hex(key_, p).substr(0, kSubjectHexChars);
        case Kind::kMap:
            if (!by_file_.empty() || by_patient_.empty()) {
                throw UsageError(
                    "the subject ids come from a map keyed by file: they cannot be derived from "
                    "a patient ID");
            }
            if (auto it = by_patient_.find(p); it != by_patient_.end()) return it->second;
            return std::nullopt;
    }
    return std::nullopt;
}

std::string patient_key(const io::Scan& scan) {
    const auto& ids = scan.meta.ids;
    if (!trim(ids.patient_id).empty()) return trim(ids.patient_id);
    return trim(ids.id);
}

std::optional<std::string> visit_date(const io::Scan& scan) {
    if (scan.meta.visit_date_ole && std::isfinite(*scan.meta.visit_date_ole) &&
        *scan.meta.visit_date_ole > 0.0) {
        return io::ole_date_to_iso_date(*scan.meta.visit_date_ole);
    }
    if (scan.meta.exam_time_filetime && *scan.meta.exam_time_filetime > 0) {
        return io::filetime_to_iso(*scan.meta.exam_time_filetime).substr(0, 10);
    }
    return std::nullopt;
}

// ---- File facts and the resume record ----------------------------------------------------

namespace {
std::string& eye_key_secret() {
    static std::string secret;
    return secret;
}
}  // namespace

void set_eye_key_secret(std::string secret) { eye_key_secret() = std::move(secret); }

std::string eye_key(const std::string& abs_path, const std::string& secret) {
    if (secret.empty()) return io::sha256_hex(abs_path).substr(0, 16);
    return io::hmac_sha256_hex(secret, abs_path).substr(0, 16);
}

std::string eye_key(const std::string& abs_path) { return eye_key(abs_path, eye_key_secret()); }

std::string read_key_file(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw InputError::unreadable(path, std::strerror(errno));
    std::string k(2 * kKeyFileBytes + 2, '\0');  // one byte more than a good file holds
    in.read(k.data(), static_cast<std::streamsize>(k.size()));
    if (in.bad()) throw InputError::unreadable(path, "read failed");
    k.resize(static_cast<std::size_t>(in.gcount()));
    if (!k.empty() && k.back() == '\n') k.pop_back();
    const bool hex = k.size() == 2 * kKeyFileBytes &&
                     std::all_of(k.begin(), k.end(), [](char c) {
                         return (c >= '0' && c <= '9') || (c >= 'a' && c <= 'f');
                     });
    if (!hex) {
        throw InputError::corrupt(path,
                                  "damaged key file (not one line of 64 hex digits): restore it "
                                  "from a backup of its output folder, or start a new folder");
    }
    return k;
}

void add_eye_key_option(CLI::App* cmd, std::string& file) {
    cmd->add_option("--eye-key-file", file,
                    "Eye key (cohort.eye_key, the CSV's eye_key) = HMAC-SHA256 of the path under "
                    "this key: a cohort's OUTDIR/private/eye.key, so that `merge` of per-scan "
                    "results gives that cohort's keys. Without it: SHA-256 of the path, which "
                    "whoever can guess the path can recompute");
}

std::string absolute_path(const std::string& file) {
    return fs::absolute(fs::path(file)).lexically_normal().string();
}

std::string log_name(const std::string& file, const char* noun) {
    const std::string key = eye_key(absolute_path(file));
    spdlog::debug("{} {} is {}", noun, key, file);
    return std::string(noun) + " " + key;
}

FileFacts file_facts(const std::string& file) {
    struct stat st {};
    if (::stat(file.c_str(), &st) != 0) {
        if (errno == ENOENT) throw InputError::missing(file);
        throw InputError::unreadable(file, std::strerror(errno));
    }
    FileFacts f;
    f.path = absolute_path(file);
    f.size = static_cast<std::uintmax_t>(st.st_size);
    f.mtime_ns = static_cast<std::int64_t>(st.st_mtim.tv_sec) * 1000000000LL +
                 static_cast<std::int64_t>(st.st_mtim.tv_nsec);
    return f;
}

nlohmann::ordered_json cohort_record(const FileFacts& facts,
                                     const std::string& options_text,
                                     std::optional<retina::ScanType> scan_type) {
    using retina::record::Name;
    using retina::record::name;
    nlohmann::ordered_json c;
    c[name(Name::kEyeKey)] = eye_key(facts.path);
    c[name(Name::kSizeBytes)] = facts.size;
    c[name(Name::kMtimeNs)] = facts.mtime_ns;
    c[name(Name::kOptions)] = options_text;
    c[name(Name::kFingerprint)] = fingerprint(options_text);
    c[name(Name::kScanType)] = scan_type ? retina::to_string(*scan_type) : "unknown";
    return c;
}

RecordState record_state(const nlohmann::json& r,
                         const FileFacts& facts,
                         const std::string& options_text) {
    if (!r.is_object()) return RecordState::kFileChanged;
    auto eq = [&](const std::string& key, const auto& value) {
        const auto it = r.find(key);
        if (it == r.end()) return false;
        try {
            return *it == nlohmann::json(value);
        } catch (const nlohmann::json::exception&) {
            return false;
        }
    };
    using retina::record::Name;
    using retina::record::name;
    if (!(eq(name(Name::kEyeKey), eye_key(facts.path)) && eq(name(Name::kSizeBytes), facts.size) &&
          eq(name(Name::kMtimeNs), facts.mtime_ns))) {
        return RecordState::kFileChanged;
    }
    return eq(name(Name::kFingerprint), fingerprint(options_text)) ? RecordState::kCurrent
                                                         : RecordState::kFingerprintChanged;
}

bool record_is_current(const nlohmann::json& r,
                       const FileFacts& facts,
                       const std::string& options_text) {
    return record_state(r, facts, options_text) == RecordState::kCurrent;
}

// ---- eyes.csv -----------------------------------------------------------------------------

GroupMap GroupMap::load(const std::string& path, const SubjectSource& subjects) {
    const auto [key_name, rows] =
        read_map(path, "group", {"subject_id", "patient_id", "file"});
    GroupMap g;
    g.path_ = path;
    g.key_ = key_name == "file" ? "file" : "subject_id";
    for (const auto& [k, v] : rows) {
        if (key_name == "patient_id") {
            // Translated now: the patient ID itself is never kept or written.
            if (const auto s = subjects.of_patient(k)) g.map_[*s] = v;
        } else {
            g.map_[k] = v;
        }
    }
    return g;
}

std::string GroupMap::group_of(const std::string& subject_id, const std::string& key) const {
    if (path_.empty()) return "NA";
    ++asked_;
    const std::string g = lookup(subject_id, key);
    if (g != "NA") ++matched_;
    return g;
}

std::string GroupMap::lookup(const std::string& subject_id, const std::string& key) const {
    if (key_ == "subject_id") {
        const auto it = map_.find(subject_id);
        return it == map_.end() ? "NA" : it->second;
    }
    const auto p = paths_.find(key);
    if (p == paths_.end()) return "NA";
    if (auto it = map_.find(p->second); it != map_.end()) return it->second;
    if (auto it = map_.find(fs::path(p->second).filename().string()); it != map_.end()) {
        return it->second;
    }
    return "NA";
}

void GroupMap::check_matches() const {
    if (path_.empty() || asked_ == 0) return;
    if (matched_ == 0) {
        throw InputError::corrupt(path_, "the groups file matches none of the " +
                                             std::to_string(asked_) + " eyes (keyed by " +
                                             key_ + ")");
    }
    if (matched_ < asked_) {
        spdlog::warn("{}: the groups file matches {} of {} eyes; the others get group NA", path_,
                     matched_, asked_);
    }
}

std::map<std::string, std::string> load_input_paths(const std::string& path) {
    const io::CsvTable t = read_small_table(path);
    // The private inputs table (record::inputs_columns()): the key and the path lead.
    using retina::record::Name;
    using retina::record::name;
    if (t.header.size() < 2 || t.header[0] != name(Name::kEyeKey) ||
        t.header[1] != name(Name::kFile)) {
        throw InputError::corrupt(path, "header must begin with " + name(Name::kEyeKey) + "," +
                                            name(Name::kFile));
    }
    std::map<std::string, std::string> paths;
    for (std::size_t i = 0; i < t.rows.size(); ++i) {
        if (t.rows[i][0].empty()) {
            throw InputError::corrupt(path, "row " + std::to_string(i + 1) +
                                                ": expected eye_key,file");
        }
        paths[t.rows[i][0]] = t.rows[i][1];
    }
    return paths;
}

void attach_cohort_record(nlohmann::ordered_json& j,
                          const std::vector<std::string>& type_columns,
                          const std::vector<std::string>& type_values,
                          const FileFacts& facts,
                          const std::string& options_text,
                          retina::ScanType scan_type,
                          const io::Scan& scan,
                          const SubjectSource& subjects,
                          const std::string& file) {
    using retina::record::Name;
    using retina::record::name;
    nlohmann::ordered_json row;
    for (std::size_t i = 0; i < type_columns.size() && i < type_values.size(); ++i) {
        row[type_columns[i]] = type_values[i];
    }
    j[name(Name::kCsvRow)] = row;
    auto rec = cohort_record(facts, options_text, scan_type);
    const auto subject = subjects.subject_id(scan, facts.path);
    rec[name(Name::kSubjectId)] = subject ? nlohmann::json(*subject) : nlohmann::json(nullptr);
    if (!subject && subjects.kind() != SubjectSource::Kind::kNone) {
        spdlog::warn("{}: no subject id for this eye (NA)", log_name(file));
    }
    const auto visit = visit_date(scan);
    rec[name(Name::kVisitDate)] = visit ? nlohmann::json(*visit) : nlohmann::json(nullptr);
    rec[name(Name::kEye)] = std::string(io::to_string(scan.meta.laterality));
    rec[name(Name::kScanPattern)] = std::string(io::to_string(scan.meta.pattern));
    rec[name(Name::kNumBscans)] = scan.num_bscans();
    j[name(Name::kCohort)] = rec;
}

std::vector<std::string> eyes_type_header(retina::ScanType scan_type) {
    switch (scan_type) {
        case retina::ScanType::kMacula:
            return retina::macula_csv_header();
        case retina::ScanType::kOnh:
            return retina::onh_csv_header();
        case retina::ScanType::kUnsupported:
            break;
    }
    throw UsageError(std::string("no eyes table for scan type '") + retina::to_string(scan_type) +
                     "'");
}

std::string eyes_csv(const std::vector<nlohmann::json>& eyes,
                     const std::vector<std::string>& names,
                     retina::ScanType scan_type,
                     const GroupMap& groups,
                     bool fingerprint_column) {
    using retina::record::Name;
    using retina::record::name;
    const auto type_cols = eyes_type_header(scan_type);
    const std::vector<std::string> header = retina::record::eyes_header(type_cols, fingerprint_column);
    std::vector<retina::record::Row> rows;
    for (std::size_t i = 0; i < eyes.size(); ++i) {
        const auto& e = eyes[i];
        const std::string& input_name = i < names.size() ? names[i] : std::string("(input)");
        const auto c = e.find(name(Name::kCohort));
        const auto csv = e.find(name(Name::kCsvRow));
        if (c == e.end() || !c->is_object() || csv == e.end() || !csv->is_object()) {
            throw InputError::corrupt(input_name, "not a per-eye result of octshape " +
                                                      std::string(kVersion) + " (no \"" +
                                                      name(Name::kCohort) + "\" record or \"" +
                                                      name(Name::kCsvRow) + "\")");
        }
        const auto field = [&](Name n) { return str_or_na(c->value(name(n), nlohmann::json())); };
        if (field(Name::kScanType) != retina::to_string(scan_type)) continue;
        retina::record::Row row;
        // The parameter columns first: a record column of the same name (none today) wins.
        for (const auto& col : type_cols) row[col] = str_or_na(csv->value(col, nlohmann::json()));
        for (const Name n : {Name::kSubjectId, Name::kEye, Name::kVisitDate, Name::kScanType,
                             Name::kEyeKey, Name::kScanPattern, Name::kNumBscans,
                             Name::kFingerprint}) {
            row[name(n)] = field(n);
        }
        const auto in = e.find(name(Name::kInput));
        row[name(Name::kSha256)] = in != e.end() && in->is_object()
                                       ? str_or_na(in->value(name(Name::kSha256), nlohmann::json()))
                                       : std::string("NA");
        row[name(Name::kGroup)] =
            groups.group_of(row[name(Name::kSubjectId)], row[name(Name::kEyeKey)]);
        rows.push_back(std::move(row));
    }
    return retina::record::eyes_table(header, rows);
}

nlohmann::json read_json_file(const std::string& path) {
    const std::string text = slurp_input(path);
    try {
        return nlohmann::json::parse(text);
    } catch (const nlohmann::json::parse_error& e) {
        throw InputError::corrupt(path, std::string("not JSON: ") + e.what());
    }
}

}  // namespace octshape::app
