#include "octshape/retina/record.h"

#include <algorithm>
#include <array>
#include <cstddef>

#include "octshape/retina/report_util.h"

namespace octshape::retina::record {
namespace {

constexpr std::size_t kNames = static_cast<std::size_t>(Name::kCount_);

// The one place the names are written.
std::array<std::string, kNames>& table() {
    static std::array<std::string, kNames> t{
        "cohort",    "input",     "csv_row",                                       // slim
        "subject_id", "eye",      "visit_date", "scan_type", "eye_key", "sha256",  // ids
        "group",                                                                   //
        "size_bytes", "mtime_ns", "options",    "fingerprint",                     // cohort
        "analysis",  "scan_pattern", "num_bscans",                                 // scan
        "file",      "reason",    "exit_code",  "result",                          // failures
    };
    return t;
}

std::string na_if_absent(const Row& r, const std::string& column) {
    const auto it = r.find(column);
    return it == r.end() ? std::string("NA") : it->second;
}

}  // namespace

const std::string& name(Name n) { return table()[static_cast<std::size_t>(n)]; }

std::vector<std::string> names(const std::vector<Name>& ns) {
    std::vector<std::string> out;
    out.reserve(ns.size());
    for (const Name n : ns) out.push_back(name(n));
    return out;
}

const std::vector<Name>& eyes_id_columns() {
    static const std::vector<Name> c{Name::kSubjectId, Name::kEye,    Name::kVisitDate,
                                     Name::kScanType,  Name::kEyeKey, Name::kSha256,
                                     Name::kGroup};
    return c;
}

const std::vector<Name>& eyes_scan_columns() {
    static const std::vector<Name> c{Name::kScanPattern, Name::kNumBscans};
    return c;
}

const std::vector<Name>& eyes_sort_columns() {
    static const std::vector<Name> c{Name::kSubjectId, Name::kEye, Name::kVisitDate,
                                     Name::kEyeKey};
    return c;
}

std::vector<std::string> eyes_non_parameter_columns() {
    std::vector<std::string> c = names(eyes_id_columns());
    c.push_back(name(Name::kAnalysis));
    for (const auto& s : names(eyes_scan_columns())) c.push_back(s);
    c.push_back(name(Name::kFingerprint));
    return c;
}

const std::vector<Name>& slim_keys() {
    static const std::vector<Name> k{Name::kCohort, Name::kInput, Name::kCsvRow};
    return k;
}

std::vector<std::string> eyes_header(const std::vector<std::string>& type_columns,
                                     bool fingerprint_column) {
    std::vector<std::string> h = names(eyes_id_columns());
    h.insert(h.end(), type_columns.begin(), type_columns.end());
    for (const auto& s : names(eyes_scan_columns())) h.push_back(s);
    if (fingerprint_column) h.push_back(name(Name::kFingerprint));
    return h;
}

std::string eyes_table(const std::vector<std::string>& header, const std::vector<Row>& rows) {
    std::vector<std::vector<std::string>> laid;
    laid.reserve(rows.size());
    for (const Row& r : rows) {
        std::vector<std::string> v;
        v.reserve(header.size());
        for (const auto& c : header) v.push_back(na_if_absent(r, c));
        laid.push_back(std::move(v));
    }
    std::vector<std::size_t> keys;
    for (const auto& k : names(eyes_sort_columns())) {
        const auto it = std::find(header.begin(), header.end(), k);
        if (it != header.end()) keys.push_back(static_cast<std::size_t>(it - header.begin()));
    }
    std::stable_sort(laid.begin(), laid.end(), [&](const auto& a, const auto& b) {
        for (const std::size_t k : keys) {
            if (a[k] != b[k]) return a[k] < b[k];
        }
        return false;
    });
    std::string out = csv_line(header);
    for (const auto& r : laid) out += csv_line(r);
    return out;
}

std::vector<std::string> failures_columns(bool with_paths) {
    if (with_paths) {
        return names({Name::kEyeKey, Name::kFile, Name::kReason, Name::kExitCode});
    }
    return names({Name::kEyeKey, Name::kReason, Name::kExitCode});
}

std::vector<std::string> inputs_columns() {
    return names({Name::kEyeKey, Name::kFile, Name::kSha256, Name::kResult});
}

std::string eyes_table_file(ScanType t) {
    return t == ScanType::kOnh ? "eyes_onh.csv" : "eyes.csv";
}

std::optional<ScanType> parse_scan_type(std::string_view s) {
    for (const ScanType t : {ScanType::kMacula, ScanType::kOnh}) {
        if (s == to_string(t)) return t;
    }
    return std::nullopt;
}

namespace testing {
ScopedRename::ScopedRename(Name n, std::string renamed) : n_(n), previous_(name(n)) {
    table()[static_cast<std::size_t>(n)] = std::move(renamed);
}
ScopedRename::~ScopedRename() { table()[static_cast<std::size_t>(n_)] = std::move(previous_); }
}  // namespace testing

}  // namespace octshape::retina::record
