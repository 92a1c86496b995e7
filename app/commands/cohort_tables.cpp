// The tables of a cohort output folder: eyes.csv, eyes_onh.csv, failures.csv, the QC gallery.

#include "commands/cohort_tables.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <map>
#include <set>

#include "commands/gallery.h"
#include "commands/provenance.h"
#include "octshape/io/sha256.h"
#include "octshape/io/atomic_file.h"
#include "octshape/retina/report_util.h"
#include "octshape/retina/record.h"

namespace octshape::app {

namespace fs = std::filesystem;
namespace record = retina::record;
using record::Name;

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
        add(it.key, it.path, it.failure.value(record::name(Name::kReason), std::string()),
            it.failure.value(record::name(Name::kExitCode), 0));
    }
    for (const auto& s : skipped) add(s.key, s.path, s.reason, s.exit_code);
    std::sort(rows.begin(), rows.end());
    std::string s = retina::csv_line(record::failures_columns(with_paths));
    for (const auto& r : rows) s += retina::csv_line(r);
    return s;
}

std::string inputs_csv(const std::vector<Item>& items, const std::vector<Skipped>& skipped) {
    std::vector<std::vector<std::string>> rows;
    for (const auto& it : items) {
        std::string sha;
        const std::string& input = record::name(Name::kInput);
        if (it.done && it.slim.contains(input) && it.slim[input].is_object()) {
            sha = it.slim[input].value(record::name(Name::kSha256), std::string());
        }
        rows.push_back({it.key, it.path, sha, it.done ? "eye" : (it.failed ? "failure" : "")});
    }
    for (const auto& s : skipped) rows.push_back({s.key, s.path, "", "failure"});
    std::sort(rows.begin(), rows.end());
    std::string s = retina::csv_line(record::inputs_columns());
    for (const auto& r : rows) s += retina::csv_line(r);
    return s;
}

std::string tables_provenance(const std::vector<Item>& items, const GroupMap& groups, bool qc) {
    Provenance p("cohort tables");
    std::vector<const Item*> done;
    for (const auto& it : items) {
        if (it.done) done.push_back(&it);
    }
    std::sort(done.begin(), done.end(),
              [](const Item* a, const Item* b) { return a->key < b->key; });
    std::set<std::string> fingerprints;
    std::map<std::string, nlohmann::ordered_json> options;  // by the canonical text
    for (const Item* it : done) {
        std::string sha;
        const std::string& input = record::name(Name::kInput);
        const std::string& cohort = record::name(Name::kCohort);
        if (it->slim.contains(input) && it->slim[input].is_object()) {
            sha = it->slim[input].value(record::name(Name::kSha256), std::string());
        }
        p.add_input(sha, "", {{record::name(Name::kEyeKey), it->key}});
        if (it->slim.contains(cohort) && it->slim[cohort].is_object()) {
            const auto& c = it->slim[cohort];
            fingerprints.insert(c.value(record::name(Name::kFingerprint), std::string()));
            const std::string text = c.value(record::name(Name::kOptions), std::string());
            options.emplace(text, options_from_text(text));
        }
    }
    nlohmann::ordered_json o;
    o["groups_sha256"] =
        groups.path().empty() ? nlohmann::ordered_json(nullptr)
                              : nlohmann::ordered_json(io::sha256_file(groups.path()));
    o["qc"] = qc;
    o["eye_fingerprints"] = fingerprints;
    o["eye_options"] = nlohmann::ordered_json::array();
    for (const auto& [text, parsed] : options) o["eye_options"].push_back(parsed);
    p.set_options(std::move(o));
    return p.json_untimed().dump(2) + "\n";
}

CohortTables write_cohort_tables(const fs::path& out, const std::vector<Item>& items,
                                 const std::vector<Skipped>& skipped, GroupMap groups, bool qc) {
    std::vector<nlohmann::json> eyes;
    std::vector<std::string> names;
    std::size_t failed = skipped.size();
    for (const auto& it : items) {
        if (it.done) {
            eyes.push_back(it.slim);
            names.push_back(eye_result_file(out, it.key).string());
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
    using retina::ScanType;
    const auto is_onh = [](const nlohmann::json& e) {
        const std::string& cohort = record::name(Name::kCohort);
        return e.contains(cohort) && e[cohort].is_object() &&
               e[cohort].value(record::name(Name::kScanType), std::string()) ==
                   retina::to_string(ScanType::kOnh);
    };
    const std::string macula_table = eyes_csv(eyes, names, ScanType::kMacula, groups);
    const bool any_onh = std::any_of(eyes.begin(), eyes.end(), is_onh);
    const std::string onh_table = any_onh ? eyes_csv(eyes, names, ScanType::kOnh, groups) : "";
    groups.check_matches();  // before any table is written
    const fs::path private_dir = make_private_dir(out);
    const fs::path macula_file = out / record::eyes_table_file(ScanType::kMacula);
    const fs::path onh_file = out / record::eyes_table_file(ScanType::kOnh);
    io::write_text_atomically(macula_file.string(), macula_table);
    if (any_onh) io::write_text_atomically(onh_file.string(), onh_table);
    io::write_text_atomically((out / "failures.csv").string(),
                              failures_csv(items, skipped, false));
    io::write_text_atomically((out / "provenance.json").string(),
                              tables_provenance(items, groups, qc));
    io::write_text_atomically((private_dir / "failures.csv").string(),
                              failures_csv(items, skipped, true));
    io::write_text_atomically((private_dir / "inputs.csv").string(), inputs_csv(items, skipped));
    // Each count once, naming the table that holds it.
    const auto onh_eyes = static_cast<std::size_t>(std::count_if(eyes.begin(), eyes.end(), is_onh));
    std::string where = std::to_string(eyes.size() - onh_eyes) + " in " + macula_file.string();
    if (any_onh) where += ", " + std::to_string(onh_eyes) + " in " + onh_file.string();
    spdlog::info("{} eyes analysed ({}); {} failed (see {}; their paths in {})", eyes.size(),
                 where, failed, (out / "failures.csv").string(),
                 (private_dir / "failures.csv").string());
    if (qc) {
        const GalleryResult g = write_qc_gallery(out);
        spdlog::info("QC gallery: {} ({} eyes, {} failures, {} pictures)",
                     (out / "qc" / "index.html").string(), g.eyes, g.failures, g.pictures);
    }
    return {eyes.size(), failed};
}

}  // namespace octshape::app
