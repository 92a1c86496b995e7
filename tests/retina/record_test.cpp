// The record (octshape/retina/record.h): one definition of every per-eye table column, read and
// written from it. A column renamed there is renamed for every writer and reader; the
// documentation lists exactly the columns the code writes, in order.

#include "octshape/retina/record.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <fstream>
#include <set>
#include <sstream>

#include "octshape/error.h"
#include "octshape/retina/cube_report.h"
#include "octshape/retina/eye_stats.h"
#include "octshape/retina/onh_report.h"
#include "test_paths.h"

namespace octshape::retina {
namespace {

using record::Name;

// Six scans of three eyes (subject S1 OD twice, S1 OS, S2 OD three times), in no order: the
// writer sorts them.
std::vector<record::Row> six_scans(const std::vector<std::string>& header) {
    const auto n = [](Name x) { return record::name(x); };
    std::vector<record::Row> rows;
    const std::vector<std::array<std::string, 5>> scans{
        {"S2", "OD", "2024-02-01", "k5", "0.21"}, {"S1", "OD", "2024-01-02", "k2", "0.25"},
        {"S2", "OD", "2024-01-01", "k4", "0.20"}, {"S1", "OD", "2024-01-01", "k9", "0.24"},
        {"S1", "OS", "2024-01-01", "k3", "0.26"}, {"S2", "OD", "2024-03-01", "k6", "0.22"},
    };
    for (const auto& s : scans) {
        record::Row r;
        for (const auto& c : header) r[c] = "NA";
        r[n(Name::kSubjectId)] = s[0];
        r[n(Name::kEye)] = s[1];
        r[n(Name::kVisitDate)] = s[2];
        r[n(Name::kEyeKey)] = s[3];
        r["cft_mm"] = s[4];
        r[n(Name::kAnalysis)] = "volume";
        r[n(Name::kScanType)] = "macula";
        r[n(Name::kScanPattern)] = "volume";
        r[n(Name::kNumBscans)] = "49";  // numeric, yet no parameter
        r[n(Name::kGroup)] = s[0] == "S1" ? "case" : "control";
        rows.push_back(std::move(r));
    }
    return rows;
}

EyeTable parse(const std::string& csv) {
    std::istringstream in(csv);
    return read_eye_table(in, "eyes.csv");
}

std::vector<std::string> column(const EyeTable& t, const std::string& name) {
    const int c = t.column(name);
    std::vector<std::string> v;
    if (c < 0) return v;
    for (const auto& r : t.rows) v.push_back(r[static_cast<std::size_t>(c)]);
    return v;
}

TEST(Record, ARenamedColumnIsRenamedForEveryWriterAndReader) {
    // Renamed in the one place: the writer's header, its sort, the parameter tables' headers
    // (cube and ONH's `analysis`), the failures table and the stats reader all follow.
    const record::testing::ScopedRename key(Name::kEyeKey, "scan_key");
    const record::testing::ScopedRename visit(Name::kVisitDate, "visit");
    const record::testing::ScopedRename analysis(Name::kAnalysis, "analysis_kind");
    const auto header = record::eyes_header(macula_csv_header(), false);
    const EyeTable t = parse(record::eyes_table(header, six_scans(header)));
    EXPECT_EQ(t.header, header);
    EXPECT_GE(t.column("scan_key"), 0);
    EXPECT_GE(t.column("visit"), 0);
    EXPECT_GE(t.column("analysis_kind"), 0);
    EXPECT_LT(t.column("eye_key"), 0);
    EXPECT_LT(t.column("visit_date"), 0);
    EXPECT_EQ(onh_csv_header().back(), "analysis_kind");
    EXPECT_EQ(record::failures_columns(false).front(), "scan_key");
    // Sorted by subject, eye, visit, key under their new names.
    EXPECT_EQ(column(t, "scan_key"),
              (std::vector<std::string>{"k9", "k2", "k3", "k4", "k5", "k6"}));

    // The stats reader finds the renamed identifiers: the first scan of each eye by visit then
    // key, and neither the key nor num_bscans (numeric) is taken for a parameter.
    const GroupStats g = group_stats(t, {});
    ASSERT_EQ(g.parameters.size(), 1U);
    EXPECT_EQ(g.parameters[0].parameter, "cft_mm");
    ASSERT_EQ(g.groups.size(), 2U);  // case (S1: 2 eyes), control (S2: 1 eye)
    EXPECT_EQ(g.groups[0].eyes, 2U);
    EXPECT_EQ(g.groups[1].eyes, 1U);
    EXPECT_DOUBLE_EQ(g.parameters[0].per_group[1].mean, 0.20);  // S2's first visit
    const RetestStats r = retest_stats(t, {}, "group");
    EXPECT_EQ(r.repeated_eyes, 2U);
    EXPECT_EQ(r.k, 2);
}

TEST(Record, ReadersRefuseATableWithoutTheRecordsColumns) {
    // A table written under other names is not read under these: the reader names the column.
    std::string csv;
    {
        const record::testing::ScopedRename key(Name::kEyeKey, "scan_key");
        const auto header = record::eyes_header({"cft_mm"}, false);
        csv = record::eyes_table(header, six_scans(header));
    }
    const EyeTable t = parse(csv);
    try {
        (void)group_stats(t, {});
        FAIL() << "a table without eye_key was read";
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("'eye_key'"), std::string::npos) << e.what();
    }
}

TEST(Record, ScanTypesByTheirNames) {
    EXPECT_EQ(record::parse_scan_type("macula"), ScanType::kMacula);
    EXPECT_EQ(record::parse_scan_type("onh"), ScanType::kOnh);
    EXPECT_FALSE(record::parse_scan_type("unsupported"));
    EXPECT_FALSE(record::parse_scan_type("auto"));
    EXPECT_EQ(record::eyes_table_file(ScanType::kMacula), "eyes.csv");
    EXPECT_EQ(record::eyes_table_file(ScanType::kOnh), "eyes_onh.csv");
}

// The QC gallery shows each eye's key parameters by their names: every one must be a column the
// tables write (and so a key of the JSON's "parameters"), or a renamed column would silently
// vanish from the page (as "mrw_mm", never a column, did before the names came from here).
TEST(Record, TheGallerysKeyParametersAreColumnsTheTablesWrite) {
    const auto check = [](const std::vector<std::string>& keys,
                          const std::vector<std::string>& header, const char* what) {
        EXPECT_FALSE(keys.empty()) << what;
        EXPECT_EQ(std::set<std::string>(keys.begin(), keys.end()).size(), keys.size()) << what;
        for (const auto& k : keys) {
            EXPECT_NE(std::find(header.begin(), header.end(), k), header.end())
                << what << ": key parameter " << k << " is not a column";
        }
    };
    check(macula_key_columns(), macula_csv_header(), "macula");
    check(onh_key_columns(), onh_csv_header(), "onh");
}

// ---- The documentation lists exactly what the code writes -----------------------------------

std::string read_text(const std::filesystem::path& p) {
    std::ifstream in(p);
    std::ostringstream s;
    s << in.rdbuf();
    return s.str();
}

std::vector<std::string> split_names(const std::string& text) {
    std::vector<std::string> out;
    std::string cur;
    for (const char c : text + ",") {
        if (c == ',') {
            const auto b = cur.find_first_not_of(" \n");
            const auto e = cur.find_last_not_of(" \n");
            if (b != std::string::npos) out.push_back(cur.substr(b, e - b + 1));
            cur.clear();
        } else {
            cur += c;
        }
    }
    return out;
}

// The documented list after `<!-- record: NAME -->` in `doc`: the first backticked span after
// the marker, split at its commas.
std::vector<std::string> documented(const std::string& doc, const std::string& name) {
    const std::string marker = "<!-- record: " + name + " -->";
    const auto at = doc.find(marker);
    if (at == std::string::npos) return {};
    const auto open = doc.find('`', at);
    const auto close = open == std::string::npos ? open : doc.find('`', open + 1);
    if (close == std::string::npos) return {};
    return split_names(doc.substr(open + 1, close - open - 1));
}

std::string common_prefix(const std::string& a, const std::string& b) {
    std::size_t n = 0;
    while (n < a.size() && n < b.size() && a[n] == b[n]) ++n;
    std::string p = a.substr(0, n);
    return p.substr(0, p.rfind('_') == std::string::npos ? 0 : p.rfind('_') + 1);
}

// `doc` with each "A, …, B" expanded from the code's order `code`. An elision may only stand for
// one family (every elided name starting with A's and B's common prefix, e.g. mrw_sector_) or
// for names documented in full elsewhere (`elsewhere`); otherwise it stays "…" and the
// comparison fails.
std::vector<std::string> expand(const std::vector<std::string>& doc,
                                const std::vector<std::string>& code,
                                const std::set<std::string>& elsewhere) {
    std::vector<std::string> out;
    for (std::size_t i = 0; i < doc.size(); ++i) {
        if (doc[i] != "…" || out.empty() || i + 1 >= doc.size()) {
            out.push_back(doc[i]);
            continue;
        }
        const auto a = std::find(code.begin(), code.end(), out.back());
        const auto b = std::find(code.begin(), code.end(), doc[i + 1]);
        if (a == code.end() || b == code.end() || b <= a) {
            out.push_back(doc[i]);
            continue;
        }
        const std::string family = common_prefix(*a, *b);
        const bool ok = std::all_of(a + 1, b, [&](const std::string& n) {
            return (family.size() >= 4 && n.rfind(family, 0) == 0) || elsewhere.contains(n);
        });
        if (!ok) {
            out.push_back(doc[i]);
            continue;
        }
        out.insert(out.end(), a + 1, b);
    }
    return out;
}

TEST(Record, OutputsMdListsEveryColumnOfEveryTableInOrder) {
    const std::string doc = read_text(test::source_dir() / "docs" / "outputs.md");
    const auto with = [](std::vector<std::string> a, const std::vector<std::string>& b) {
        a.insert(a.end(), b.begin(), b.end());
        return a;
    };
    const auto scan_cols = record::names(
        {Name::kEyeKey, Name::kSha256, Name::kEye, Name::kScanPattern, Name::kNumBscans});
    const std::vector<std::pair<std::string, std::vector<std::string>>> tables{
        {"macula --csv", with(scan_cols, macula_csv_header())},
        {"onh --csv", with(scan_cols, onh_csv_header())},
        {"eyes.csv", record::eyes_header(macula_csv_header(), false)},
        {"eyes_onh.csv", record::eyes_header(onh_csv_header(), false)},
        {"failures.csv", record::failures_columns(false)},
    };
    // The names each table's own list documents (its families expanded): what another table's
    // list may elide.
    std::set<std::string> explicit_names;
    for (const auto& [name, code] : tables) {
        for (const auto& n : expand(documented(doc, name), code, {})) explicit_names.insert(n);
    }
    explicit_names.erase("…");
    for (const auto& [name, code] : tables) {
        const auto listed = documented(doc, name);
        ASSERT_FALSE(listed.empty()) << "docs/outputs.md has no `<!-- record: " << name << " -->`";
        const auto doc_list = expand(listed, code, explicit_names);
        std::string missing;
        std::string extra;
        for (const auto& c : code) {
            if (std::find(doc_list.begin(), doc_list.end(), c) == doc_list.end()) missing += " " + c;
        }
        for (const auto& c : doc_list) {
            if (std::find(code.begin(), code.end(), c) == code.end()) extra += " " + c;
        }
        EXPECT_EQ(doc_list, code) << name << ": written but not documented:" << missing
                                  << "; documented but not written:" << extra;
    }
}

TEST(Record, StatsMdAndTheRRecipesReadmeNameTheRecordsColumns) {
    const std::string stats = read_text(test::source_dir() / "docs" / "stats.md");
    EXPECT_EQ(documented(stats, "failures.csv"), record::failures_columns(false));
    const std::string r = read_text(test::source_dir() / "docs" / "r" / "README.md");
    EXPECT_EQ(documented(r, "non-parameter columns"), record::eyes_non_parameter_columns());
}

TEST(Record, TheRRecipeSkipsTheRecordsNonParameterColumns) {
    // docs/r/octshape_gee.R reads eyes.csv by name: its identifier list is the record's.
    const std::string r = read_text(test::source_dir() / "docs" / "r" / "octshape_gee.R");
    // No std::regex (GCC 12's <regex> warns under the sanitizer build): the list by hand.
    const auto at = r.find("id_cols <- c(");
    ASSERT_NE(at, std::string::npos);
    const auto end = r.find(')', at);
    const std::string list = r.substr(at, end - at);
    std::set<std::string> in_r;
    for (auto q = list.find('"'); q != std::string::npos; q = list.find('"', q + 1)) {
        const auto close = list.find('"', q + 1);
        in_r.insert(list.substr(q + 1, close - q - 1));
        q = close;
    }
    const auto code = record::eyes_non_parameter_columns();
    EXPECT_EQ(in_r, std::set<std::string>(code.begin(), code.end()));
}

}  // namespace
}  // namespace octshape::retina
