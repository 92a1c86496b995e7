#include "octshape/retina/eye_stats.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <optional>
#include <set>
#include <sstream>
#include <system_error>
#include <tuple>

#include "octshape/error.h"
#include "octshape/io/csv.h"
#include "octshape/retina/record.h"

namespace octshape::retina {
namespace {

constexpr const char* kNoGroup = "(none)";

std::optional<double> parse_number(const std::string& s) {
    if (is_missing_field(s)) return std::nullopt;
    double v = 0.0;
    const char* first = s.data();
    const char* last = s.data() + s.size();
    const auto [ptr, ec] = std::from_chars(first, last, v);
    if (ec != std::errc() || ptr != last || !std::isfinite(v)) return std::nullopt;
    return v;
}

int require_column(const EyeTable& t, const std::string& name) {
    const int c = t.column(name);
    if (c < 0) throw InputError::corrupt("eyes.csv", "no column '" + name + "'");
    return c;
}

// The columns that identify a scan and order an eye's scans.
struct Ids {
    int subject = -1;
    int eye = -1;
    int visit = -1;
    int file = -1;  // the eye_key column (it replaced the file name: docs/cohort.md)
    explicit Ids(const EyeTable& t)
        : subject(require_column(t, record::name(record::Name::kSubjectId))),
          eye(require_column(t, record::name(record::Name::kEye))),
          visit(require_column(t, record::name(record::Name::kVisitDate))),
          file(require_column(t, record::name(record::Name::kEyeKey))) {}
};

// Row indices grouped by key, each group in visit_date then eye_key order (ISO dates sort as
// strings).
std::map<std::vector<std::string>, std::vector<std::size_t>> scans_by_key(const EyeTable& t,
                                                                          const Ids& ids,
                                                                          bool with_visit) {
    std::map<std::vector<std::string>, std::vector<std::size_t>> m;
    for (std::size_t r = 0; r < t.rows.size(); ++r) {
        const auto& row = t.rows[r];
        std::vector<std::string> key{row[ids.subject], row[ids.eye]};
        if (with_visit) key.push_back(row[ids.visit]);
        m[key].push_back(r);
    }
    for (auto& [key, rows] : m) {
        std::sort(rows.begin(), rows.end(), [&](std::size_t a, std::size_t b) {
            return std::tie(t.rows[a][ids.visit], t.rows[a][ids.file], a) <
                   std::tie(t.rows[b][ids.visit], t.rows[b][ids.file], b);
        });
    }
    return m;
}

}  // namespace


bool is_missing_field(const std::string& s) { return s.empty() || s == "NA"; }

EyeTable read_eye_table(std::istream& in, const std::string& name) { return io::read_csv(in, name); }

EyeTable read_eye_table_file(const std::string& path) { return io::read_csv_file(path); }

std::vector<std::string> eye_table_id_columns() { return record::eyes_non_parameter_columns(); }

std::vector<std::string> numeric_columns(const EyeTable& t, const std::string& group_column) {
    const auto ids = eye_table_id_columns();
    std::vector<std::string> out;
    for (std::size_t c = 0; c < t.header.size(); ++c) {
        const std::string& h = t.header[c];
        if (h == group_column || std::find(ids.begin(), ids.end(), h) != ids.end()) continue;
        bool numeric = true;
        bool any = false;
        for (const auto& row : t.rows) {
            if (is_missing_field(row[c])) continue;
            if (!parse_number(row[c])) {
                numeric = false;
                break;
            }
            any = true;
        }
        if (numeric && any) out.push_back(h);
    }
    return out;
}

void GroupStatsParams::validate() const {
    if (group_column.empty()) throw UsageError("stats: group_column must not be empty");
}

GroupStats group_stats(const EyeTable& t, const GroupStatsParams& p) {
    p.validate();
    const Ids ids(t);
    const int gcol = t.column(p.group_column);
    GroupStats out;
    out.group_column = p.group_column;
    out.all_scans = p.all_scans;

    // The scans used: every row, or the first scan of each eye.
    std::vector<std::size_t> used;
    if (p.all_scans) {
        for (std::size_t r = 0; r < t.rows.size(); ++r) used.push_back(r);
    } else {
        for (const auto& [key, rows] : scans_by_key(t, ids, false)) used.push_back(rows.front());
        std::sort(used.begin(), used.end());
    }
    auto group_of = [&](std::size_t r) -> std::string {
        if (gcol < 0) return "all";
        const std::string& g = t.rows[r][static_cast<std::size_t>(gcol)];
        return is_missing_field(g) ? kNoGroup : g;
    };
    std::map<std::string, std::vector<std::size_t>> by_group;
    for (const std::size_t r : used) by_group[group_of(r)].push_back(r);
    for (const auto& [name, rows] : by_group) {
        GroupInfo g;
        g.name = name;
        g.rows = rows.size();
        std::set<std::pair<std::string, std::string>> eyes;
        std::set<std::string> subjects;
        for (const std::size_t r : rows) {
            eyes.emplace(t.rows[r][ids.subject], t.rows[r][ids.eye]);
            subjects.insert(t.rows[r][ids.subject]);
        }
        g.eyes = eyes.size();
        g.subjects = subjects.size();
        out.groups.push_back(g);
    }
    for (const auto& name : numeric_columns(t, p.group_column)) {
        const auto c = static_cast<std::size_t>(t.column(name));
        ParameterSummaries ps;
        ps.parameter = name;
        for (const auto& [gname, rows] : by_group) {
            std::vector<double> v;
            for (const std::size_t r : rows) {
                if (const auto x = parse_number(t.rows[r][c])) v.push_back(*x);
            }
            ps.per_group.push_back(summarise(v));
        }
        out.parameters.push_back(std::move(ps));
    }
    return out;
}

void RetestParams::validate() const {
    if (sessions < 0 || sessions == 1) {
        throw UsageError("stats: sessions must be 0 (automatic) or >= 2");
    }
    icc.validate();
}

RetestStats retest_stats(const EyeTable& t,
                         const RetestParams& p,
                         const std::string& group_column) {
    p.validate();
    const Ids ids(t);
    RetestStats out;
    out.same_visit = p.same_visit;
    std::vector<std::vector<std::size_t>> repeated;
    for (const auto& [key, rows] : scans_by_key(t, ids, p.same_visit)) {
        if (rows.size() >= 2) repeated.push_back(rows);
    }
    out.repeated_eyes = repeated.size();
    if (repeated.empty()) {
        throw AnalysisError(std::string("stats --retest: no eye has two scans (repeats are ") +
                            (p.same_visit ? "scans of the same subject_id, eye and visit_date)"
                                          : "scans of the same subject_id and eye)"));
    }
    std::size_t kmin = repeated.front().size();
    for (const auto& r : repeated) kmin = std::min(kmin, r.size());
    out.k = p.sessions > 0 ? p.sessions : static_cast<int>(kmin);
    const auto k = static_cast<std::size_t>(out.k);
    std::vector<std::vector<std::size_t>> eyes;
    for (const auto& r : repeated) {
        if (r.size() >= k) eyes.emplace_back(r.begin(), r.begin() + static_cast<long>(k));
    }
    out.eyes_used = eyes.size();
    for (const auto& name : numeric_columns(t, group_column)) {
        const auto c = static_cast<std::size_t>(t.column(name));
        ParameterIcc pi;
        pi.parameter = name;
        std::vector<std::vector<double>> complete;
        for (const auto& e : eyes) {
            std::vector<double> v;
            for (const std::size_t r : e) {
                if (const auto x = parse_number(t.rows[r][c])) v.push_back(*x);
            }
            if (v.size() == k) {
                complete.push_back(std::move(v));
            } else {
                ++pi.eyes_missing;
            }
        }
        pi.icc.n = static_cast<int>(complete.size());
        pi.icc.k = out.k;
        if (complete.size() >= 2) {
            Eigen::MatrixXd m(static_cast<Eigen::Index>(complete.size()),
                              static_cast<Eigen::Index>(k));
            for (std::size_t i = 0; i < complete.size(); ++i) {
                for (std::size_t j = 0; j < k; ++j) {
                    m(static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(j)) = complete[i][j];
                }
            }
            pi.icc = icc_2_1(m, p.icc);
        }
        out.parameters.push_back(std::move(pi));
    }
    return out;
}

}  // namespace octshape::retina
