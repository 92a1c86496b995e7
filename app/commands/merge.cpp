// `octshape merge JSON...|DIR -o eyes.csv`: the eyes table from per-eye JSON results (written
// by `octshape macula -o` or by `octshape cohort` under OUTDIR/eyes). The same code path as the
// cohort's own eyes.csv (eyes_csv in commands/eye_record.h), so both give identical bytes.

#include <CLI/CLI.hpp>
#include <algorithm>
#include <filesystem>
#include <iostream>
#include <map>
#include <memory>

#include <spdlog/spdlog.h>

#include "commands/command.h"
#include "commands/eye_record.h"
#include "octshape/io/atomic_file.h"
#include "octshape/error.h"
#include "octshape/retina/record.h"

namespace octshape::app {
namespace {

namespace fs = std::filesystem;

struct MergeOptions {
    std::vector<std::string> inputs;
    std::string out;
    std::string groups;
    std::string type = retina::to_string(retina::ScanType::kMacula);  // --type
    bool allow_mixed = false;
    std::string inputs_map;   // eye_key,file (a private table) for a groups file keyed by file
    SubjectOptions subjects;  // to turn a groups file keyed by patient ID into subject ids
};

// Refuses (InputError naming a file of the minority) eyes of `type` made by different code or
// parameters, unless `allow` (then one warning; the table gets a fingerprint column).
void check_fingerprints(const std::vector<nlohmann::json>& eyes,
                        const std::vector<std::string>& files, retina::ScanType type,
                        bool allow) {
    using retina::record::Name;
    using retina::record::name;
    std::map<std::string, std::vector<std::size_t>> by;
    for (std::size_t i = 0; i < eyes.size(); ++i) {
        const auto c = eyes[i].find(name(Name::kCohort));
        if (c == eyes[i].end() || !c->is_object()) continue;  // eyes_csv refuses it
        if (c->value(name(Name::kScanType), std::string()) != retina::to_string(type)) continue;
        const auto f = c->find(name(Name::kFingerprint));
        by[f != c->end() && f->is_string() ? f->get<std::string>() : "none"].push_back(i);
    }
    if (by.size() <= 1) return;
    std::string counts;
    const std::vector<std::size_t>* smallest = nullptr;
    for (const auto& [fp, idx] : by) {
        counts += (counts.empty() ? "" : ", ") + fp + ": " + std::to_string(idx.size());
        if (smallest == nullptr || idx.size() < smallest->size()) smallest = &idx;
    }
    const std::string what = "the eyes were made by different code or parameters (" +
                             std::to_string(by.size()) + " fingerprints: " + counts + ")";
    if (!allow) {
        throw InputError::corrupt(files[smallest->front()],
                                  what + "; redo them with one octshape, or --allow-mixed "
                                         "writes the table with a fingerprint column");
    }
    spdlog::warn("{}; the fingerprint column tells them apart", what);
}

void run(const MergeOptions& o) {
    if (!o.out.empty()) io::check_output_location(o.out);  // before reading anything
    std::vector<std::string> files;
    for (const auto& in : o.inputs) {
        std::error_code ec;
        if (!fs::exists(in, ec)) throw InputError::missing(in);
        if (fs::is_directory(in, ec)) {
            // Every NAME.json directly inside (not hidden: ".NAME.tmp-*" are unfinished writes).
            for (const auto& e : fs::directory_iterator(in)) {
                const std::string name = e.path().filename().string();
                if (e.is_regular_file() && name[0] != '.' && e.path().extension() == ".json") {
                    files.push_back(e.path().string());
                }
            }
        } else {
            files.push_back(in);
        }
    }
    std::sort(files.begin(), files.end());
    GroupMap groups;
    if (!o.groups.empty()) {
        groups = GroupMap::load(o.groups, SubjectSource::from_options(o.subjects));
        if (groups.by_file()) {
            if (o.inputs_map.empty()) {
                throw UsageError(o.groups + ": a groups file keyed by file needs the inputs' "
                                 "paths, which per-eye results do not hold: give --inputs-map "
                                 "(e.g. OUTDIR/private/inputs.csv), or key it by subject_id or "
                                 "patient_id");
            }
            groups.set_paths(load_input_paths(o.inputs_map));
        }
    }
    std::vector<nlohmann::json> eyes;
    eyes.reserve(files.size());
    for (const auto& f : files) {
        nlohmann::json j = read_json_file(f);
        nlohmann::json s;
        for (const auto& k : retina::record::names(retina::record::slim_keys())) {
            if (j.contains(k)) s[k] = std::move(j[k]);
        }
        eyes.push_back(std::move(s));
    }
    const retina::ScanType type = *retina::record::parse_scan_type(o.type);  // checked by CLI11
    check_fingerprints(eyes, files, type, o.allow_mixed);
    const std::string csv = eyes_csv(eyes, files, type, groups, o.allow_mixed);
    groups.check_matches();
    if (o.out.empty()) {
        std::cout << csv;
    } else {
        io::write_text_atomically(o.out, csv);
    }
}

}  // namespace

void add_merge_command(CLI::App& app, RunContext& /*ctx*/) {
    auto opts = std::make_shared<MergeOptions>();
    namespace record = retina::record;
    const auto join = [](const std::vector<std::string>& v) {
        std::string s;
        for (const auto& x : v) s += (s.empty() ? "" : ", ") + x;
        return s;
    };
    CLI::App* cmd = app.add_subcommand(
        "merge",
        "Build eyes.csv (" + join(record::names(record::eyes_id_columns())) +
            ", then every parameter, then " + join(record::names(record::eyes_scan_columns())) +
            "; rows sorted by " + join(record::names(record::eyes_sort_columns())) +
            ") from per-eye JSON results of `octshape macula -o` or OUTDIR/eyes of a cohort "
            "(docs/cohort.md). Eyes made by different code or parameters (fingerprints) are "
            "refused");
    cmd->add_option("inputs", opts->inputs, "Per-eye JSON files or folders holding them")
        ->required();
    cmd->add_option("-o,--output", opts->out, "Write the CSV here (default: stdout)");
    cmd->add_option("--groups", opts->groups,
                    "Group column from a CSV with header subject_id,group or patient_id,group "
                    "(the patient IDs turned into subject ids with the subject option below)");
    cmd->add_flag("--allow-mixed", opts->allow_mixed,
                  "Write a table of eyes made by different code or parameters, with a last "
                  "column fingerprint telling them apart (by default refused, exit 65)");
    cmd->add_option("--inputs-map", opts->inputs_map,
                    "Private CSV with header eye_key,file (OUTDIR/private/inputs.csv of a "
                    "cohort; the workflow's): the paths a groups file keyed by file needs");
    add_subject_options(cmd, opts->subjects);
    cmd->add_option("--type", opts->type,
                    "Which eyes: macula (the eyes.csv table) or onh (eyes_onh.csv)")
        ->check(CLI::IsMember({std::string(retina::to_string(retina::ScanType::kMacula)),
                               std::string(retina::to_string(retina::ScanType::kOnh))}))
        ->capture_default_str();
    cmd->callback([opts] { run(*opts); });
}

}  // namespace octshape::app
