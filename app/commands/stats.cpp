// `octshape stats eyes.csv [--group-col group] [--retest] [-o table.csv] [--json]`: the
// per-group table of every parameter (thesis Tables 7.3, 8.2) and the test-retest ICC(2,1)
// with its 95 % CI (Tables 7.1, 8.1). Definitions and layout: docs/stats.md.

#include <CLI/CLI.hpp>
#include <spdlog/fmt/fmt.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <iostream>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>

#include "commands/command.h"
#include "commands/provenance.h"
#include "octshape/io/sha256.h"
#include "octshape/io/atomic_file.h"
#include "octshape/error.h"
#include "octshape/retina/cube_report.h"
#include "octshape/retina/eye_stats.h"
#include "octshape/retina/record.h"

namespace octshape::app {
namespace {

struct StatsOptions {
    std::string input;
    retina::GroupStatsParams groups;
    retina::RetestParams retest_params;
    bool retest = false;
    std::string table_out;
    std::string retest_out;
    std::string analysis;  // volume | radial | line; empty: the first of these the table has
    bool json = false;
};

// Fewer eyes than this in an ICC: its 95 % CI rests on an F quantile with n − 1 ≤ 8 degrees
// of freedom and is so wide that it may leave the range ICC(2,1) can take, [−1/(k−1), 1] (over
// 2 eyes a lower bound of −402 was printed). The value is given, with a warning.
constexpr std::size_t kIccFewEyes = 10;

// Full precision for files, NA for missing (R reads it as missing).
std::string num(double v) { return std::isfinite(v) ? fmt::format("{:.10g}", v) : "NA"; }
// Short form for the terminal table.
std::string short_num(double v) { return std::isfinite(v) ? fmt::format("{:.4g}", v) : "NA"; }
// "min to max" (a hyphen would read "-0.26--0.25" for negative values).
std::string range_text(double lo, double hi) { return short_num(lo) + " to " + short_num(hi); }

std::string icc_warning(const retina::IccResult& i) {
    if (i.n >= 2 && static_cast<std::size_t>(i.n) < kIccFewEyes) {
        return fmt::format("only {} eyes: the 95% CI is not informative", i.n);
    }
    return {};
}

nlohmann::ordered_json json_num(double v) {
    return std::isfinite(v) ? nlohmann::ordered_json(v) : nlohmann::ordered_json(nullptr);
}

std::string groups_csv(const retina::GroupStats& g) {
    std::string s = "parameter,group,n,mean,sd,min,max\n";
    for (const auto& p : g.parameters) {
        for (std::size_t i = 0; i < g.groups.size(); ++i) {
            const auto& m = p.per_group[i];
            s += retina::csv_field(p.parameter) + ',' + retina::csv_field(g.groups[i].name) + ',' +
                 std::to_string(m.n) + ',' + num(m.mean) + ',' + num(m.sd) + ',' + num(m.min) +
                 ',' + num(m.max) + '\n';
        }
    }
    return s;
}

std::string retest_csv(const retina::RetestStats& r) {
    std::string s = "parameter,n_eyes,k,icc,lower_95,upper_95,f,df1,df2,p,eyes_missing\n";
    for (const auto& p : r.parameters) {
        const auto& i = p.icc;
        s += retina::csv_field(p.parameter) + ',' + std::to_string(i.n) + ',' +
             std::to_string(i.k) + ',' + num(i.icc) + ',' + num(i.lower) + ',' + num(i.upper) +
             ',' + num(i.f) + ',' + std::to_string(i.df1) + ',' + std::to_string(i.df2) + ',' +
             num(i.p) + ',' + std::to_string(p.eyes_missing) + '\n';
    }
    return s;
}

// The thesis layout: one row per parameter, per group "mean (SD)" and "min-max".
std::string groups_text(const retina::GroupStats& g) {
    std::ostringstream o;
    o << (g.all_scans ? "Every scan counts.\n"
                      : "One scan per eye (subject_id + eye): the first by visit_date, then eye_key.\n");
    for (const auto& gi : g.groups) {
        o << fmt::format("group {}: {} scans, {} eyes, {} subjects\n", gi.name, gi.rows, gi.eyes,
                         gi.subjects);
    }
    o << fmt::format("{:<36}", "parameter");
    for (const auto& gi : g.groups) {
        o << fmt::format(" | {:>4} {:>22} {:>21}", "n", gi.name + " mean (SD)", "min to max");
    }
    o << '\n';
    for (const auto& p : g.parameters) {
        o << fmt::format("{:<36}", p.parameter);
        for (const auto& m : p.per_group) {
            o << fmt::format(" | {:>4} {:>22} {:>21}", m.n,
                             short_num(m.mean) + " (" + short_num(m.sd) + ")",
                             range_text(m.min, m.max));
        }
        o << '\n';
    }
    return o.str();
}

std::string retest_text(const retina::RetestStats& r) {
    std::ostringstream o;
    o << fmt::format(
        "\nTest-retest ICC(2,1) (two-way random, absolute agreement, single measurement), "
        "repeats = {}; {} eyes scanned more than once, {} with >= k = {} scans used\n",
        r.same_visit ? "same subject_id, eye and visit_date" : "same subject_id and eye",
        r.repeated_eyes, r.eyes_used, r.k);
    o << fmt::format("{:<36} {:>6} {:>8} {:>8} {:>8} {:>10}\n", "parameter", "n", "ICC", "LCI95",
                     "UCI95", "p");
    bool few = false;
    for (const auto& p : r.parameters) {
        const bool warn = !icc_warning(p.icc).empty();
        few = few || warn;
        // A value the data do not determine prints as NA, never "nan".
        const auto v = [](double x, const char* spec) {
            return std::isfinite(x) ? fmt::format(fmt::runtime(spec), x) : std::string("NA");
        };
        o << fmt::format("{:<36} {:>6} {:>8} {:>8} {:>8} {:>10}{}\n", p.parameter, p.icc.n,
                         v(p.icc.icc, "{:.4f}"), v(p.icc.lower, "{:.4f}"), v(p.icc.upper, "{:.4f}"),
                         v(p.icc.p, "{:.3g}"), warn ? " *" : "");
    }
    if (few) {
        o << fmt::format("* fewer than {} eyes: the 95% CI is not informative (it may leave the "
                         "range [-1/(k-1), 1] an ICC can take)\n",
                         kIccFewEyes);
    }
    return o.str();
}

nlohmann::ordered_json to_json(const retina::GroupStats& g,
                               const retina::RetestStats* r,
                               const std::string& input,
                               const std::string& analysis,
                               const nlohmann::ordered_json& provenance) {
    nlohmann::ordered_json j;
    j["provenance"] = provenance;
    j["input"] = input;
    if (!analysis.empty()) j["analysis"] = analysis;
    j["group_column"] = g.group_column;
    j["scans_used"] = g.all_scans ? "every scan" : "first scan of each eye (visit_date, then eye_key)";
    j["groups"] = nlohmann::ordered_json::array();
    for (const auto& gi : g.groups) {
        j["groups"].push_back(
            {{"name", gi.name}, {"scans", gi.rows}, {"eyes", gi.eyes}, {"subjects", gi.subjects}});
    }
    j["parameters"] = nlohmann::ordered_json::array();
    for (const auto& p : g.parameters) {
        nlohmann::ordered_json pj;
        pj["parameter"] = p.parameter;
        for (std::size_t i = 0; i < g.groups.size(); ++i) {
            const auto& m = p.per_group[i];
            pj["groups"][g.groups[i].name] = {{"n", m.n},
                                              {"mean", json_num(m.mean)},
                                              {"sd", json_num(m.sd)},
                                              {"min", json_num(m.min)},
                                              {"max", json_num(m.max)}};
        }
        j["parameters"].push_back(pj);
    }
    if (r != nullptr) {
        nlohmann::ordered_json rj;
        rj["method"] =
            "ICC(2,1): two-way random effects, absolute agreement, single measurement "
            "(Shrout & Fleiss 1979; McGraw & Wong 1996 ICC(A,1))";
        rj["repeats"] =
            r->same_visit ? "same subject_id, eye and visit_date" : "same subject_id and eye";
        rj["k"] = r->k;
        rj["repeated_eyes"] = r->repeated_eyes;
        rj["eyes_used"] = r->eyes_used;
        rj["parameters"] = nlohmann::ordered_json::array();
        for (const auto& p : r->parameters) {
            const auto& i = p.icc;
            rj["parameters"].push_back({{"parameter", p.parameter},
                                        {"n_eyes", i.n},
                                        {"k", i.k},
                                        {"icc", json_num(i.icc)},
                                        {"lower_95", json_num(i.lower)},
                                        {"upper_95", json_num(i.upper)},
                                        {"f", json_num(i.f)},
                                        {"df1", i.df1},
                                        {"df2", i.df2},
                                        {"p", json_num(i.p)},
                                        {"eyes_missing", p.eyes_missing}});
            if (const std::string w = icc_warning(i); !w.empty()) {
                rj["parameters"].back()["warning"] = w;
            }
        }
        j["retest"] = rj;
    }
    return j;
}

// Keeps the rows of one analysis (eyes.csv column `analysis`: volume, radial or line): a line
// scan's 2-D parameters and a radial scan's half-line fits are not the volume's and are never
// pooled with them. Returns the analysis
// kept ("" when the table has no such column).
std::string keep_one_analysis(retina::EyeTable& t, const StatsOptions& o) {
    const std::string& analysis = retina::record::name(retina::record::Name::kAnalysis);
    const int col = t.column(analysis);
    if (col < 0) {
        if (!o.analysis.empty()) {
            throw InputError::corrupt(o.input, "no column '" + analysis + "' for --analysis " +
                                                   o.analysis);
        }
        return {};
    }
    std::map<std::string, std::size_t> counts;
    for (const auto& row : t.rows) ++counts[row[static_cast<std::size_t>(col)]];
    std::string keep = o.analysis;
    if (keep.empty()) {
        keep = counts.contains("volume")   ? "volume"
               : counts.contains("radial") ? "radial"
               : counts.contains("line")   ? "line"
                                           : counts.begin()->first;
    }
    std::vector<std::vector<std::string>> kept;
    for (auto& row : t.rows) {
        if (row[static_cast<std::size_t>(col)] == keep) kept.push_back(std::move(row));
    }
    t.rows = std::move(kept);
    for (const auto& [name, n] : counts) {
        if (name == keep) continue;
        spdlog::warn("{}: {} rows of analysis '{}' left out (one analysis a table: give "
                     "--analysis {})",
                     o.input, n, name, name);
    }
    if (t.rows.empty()) {
        throw AnalysisError(o.input + ": no row of analysis '" + keep + "'");
    }
    return keep;
}

// Every effective option of a stats run (the provenance's options), defaults included.
nlohmann::ordered_json stats_options(const StatsOptions& o, const std::string& analysis) {
    return {{"group_column", o.groups.group_column},
            {"all_scans", o.groups.all_scans},
            {"analysis", analysis.empty() ? nlohmann::ordered_json(nullptr)
                                          : nlohmann::ordered_json(analysis)},
            {"retest", o.retest},
            {"same_visit", o.retest_params.same_visit},
            {"sessions", o.retest_params.sessions},
            {"icc_confidence", o.retest_params.icc.confidence},
            {"output", !o.table_out.empty()},
            {"retest_output", !o.retest_out.empty()}};
}

void run(const StatsOptions& o) {
    Provenance prov("stats");
    retina::EyeTable t = retina::read_eye_table_file(o.input);
    // failures.csv is the cohort's other table: say so.
    namespace record = retina::record;
    if (t.column(record::name(record::Name::kReason)) >= 0 &&
        t.column(record::name(record::Name::kSubjectId)) < 0) {
        std::string columns;
        for (const auto& c : record::failures_columns(false)) {
            columns += (columns.empty() ? "" : ", ") + c;
        }
        throw InputError::corrupt(o.input, "this is a failures table (" + columns +
                                               "), not eyes.csv: give the eyes.csv beside it");
    }
    const std::string analysis = keep_one_analysis(t, o);
    const retina::GroupStatsParams& groups = o.groups;
    // A group column whose every field is missing (a cohort run without --groups) is one group
    // "all", as is an absent column, not "(none)".
    if (const int gc = t.column(groups.group_column); gc >= 0) {
        const auto col = static_cast<std::size_t>(gc);
        const bool none = std::all_of(t.rows.begin(), t.rows.end(), [&](const auto& row) {
            return retina::is_missing_field(row[col]);
        });
        if (none) {
            for (auto& row : t.rows) row[col] = "all";
        }
    }
    // The library names the table "eyes.csv" in its errors: name the file given.
    const auto named = [&](const auto& compute) {
        try {
            return compute();
        } catch (const InputError& e) {
            throw InputError(e.kind(), o.input, e.reason(), e.offset());
        }
    };
    const retina::GroupStats g = named([&] { return retina::group_stats(t, groups); });
    std::unique_ptr<retina::RetestStats> r;
    if (o.retest) {
        r = std::make_unique<retina::RetestStats>(named(
            [&] { return retina::retest_stats(t, o.retest_params, groups.group_column); }));
        for (const auto& p : r->parameters) {
            if (const std::string w = icc_warning(p.icc); !w.empty()) {
                spdlog::warn("{}: ICC of {}: {}", o.input, p.parameter, w);
            }
        }
    }
    if (!o.table_out.empty()) io::write_text_atomically(o.table_out, groups_csv(g));
    if (r && !o.retest_out.empty()) io::write_text_atomically(o.retest_out, retest_csv(*r));
    if (o.json) {
        prov.mark("statistics");
        prov.add_input(io::sha256_file(o.input));
        prov.set_options(stats_options(o, analysis));
        std::cout << to_json(g, r.get(), o.input, analysis, prov.json()).dump(2) << '\n';
    } else {
        if (!analysis.empty()) {
            std::cout << "Analysis: "
                      << (analysis == "volume"   ? "volume (3-D)"
                          : analysis == "radial" ? "radial scan (3-D from the radial lines)"
                          : analysis == "line"   ? "line scan (2-D)"
                                                 : analysis)
                      << ".\n";
        }
        std::cout << groups_text(g);
        if (r) std::cout << retest_text(*r);
    }
    spdlog::info("{}: {} rows, {} groups, {} parameters", o.input, t.rows.size(), g.groups.size(),
                 g.parameters.size());
}

}  // namespace

void add_stats_command(CLI::App& app, RunContext& /*ctx*/) {
    auto opts = std::make_shared<StatsOptions>();
    CLI::App* cmd = app.add_subcommand(
        "stats",
        "Per-group n, mean (SD), min-max of every parameter in eyes.csv (thesis Tables 7.3, "
        "8.2) and, with --retest, the test-retest ICC(2,1) with 95% CI (Tables 7.1, 8.1). "
        "GEE models stay in R: docs/r/octshape_gee.R");
    cmd->add_option("eyes_csv", opts->input, "eyes.csv written by `octshape cohort`")->required();
    cmd->add_option("--group-col", opts->groups.group_column,
                    "Column holding the group (absent, or every field empty/NA: one group "
                    "'all'; rows with a missing group among others: '(none)')")
        ->capture_default_str();
    cmd->add_flag("--all-scans", opts->groups.all_scans,
                  "Group table over every scan (default: the first scan of each eye)");
    cmd->add_flag("--retest", opts->retest,
                  "ICC(2,1) over eyes scanned more than once (same subject_id and eye)");
    cmd->add_flag("--same-visit", opts->retest_params.same_visit,
                  "--retest: only scans of the same visit_date are repeats");
    cmd->add_option("--sessions", opts->retest_params.sessions,
                    "--retest: scans per eye k (0 = the fewest any repeated eye has)")
        ->capture_default_str();
    cmd->add_option("-o,--output", opts->table_out,
                    "Write the group table as CSV (parameter,group,n,mean,sd,min,max)");
    cmd->add_option("--retest-output", opts->retest_out,
                    "Write the ICC table as CSV (parameter,n_eyes,k,icc,lower_95,upper_95,...)");
    cmd->add_option("--analysis", opts->analysis,
                    "Rows of one analysis only, volume, radial or line (default: volume when "
                    "there are volume rows, else radial, else line; the other rows are left out "
                    "with a warning, never pooled)")
        ->check(CLI::IsMember({"volume", "radial", "line"}));
    cmd->add_flag("--json", opts->json, "Print JSON on stdout instead of the text tables");
    cmd->callback([opts] { run(*opts); });
}

}  // namespace octshape::app
