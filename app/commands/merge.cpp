// `octshape merge JSON...|DIR -o eyes.csv`: the eyes table from per-eye JSON results (written
// by `octshape macula -o` or by `octshape cohort` under OUTDIR/eyes). The same code path as the
// cohort's own eyes.csv (eyes_csv in commands/eye_record.h), so both give identical bytes.

#include <algorithm>
#include <filesystem>
#include <iostream>
#include <memory>

#include "commands/command.h"
#include "commands/eye_record.h"
#include "octshape/io/atomic_file.h"
#include "octshape/error.h"

namespace octshape::app {
namespace {

namespace fs = std::filesystem;

struct MergeOptions {
    std::vector<std::string> inputs;
    std::string out;
    std::string groups;
    std::string type = "macula";
};

void run(const MergeOptions& o) {
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
    if (!o.groups.empty()) groups = GroupMap::load(o.groups);
    std::vector<nlohmann::json> eyes;
    eyes.reserve(files.size());
    for (const auto& f : files) {
        nlohmann::json j = read_json_file(f);
        nlohmann::json s;
        for (const char* k : {"cohort", "input", "csv_row"}) {
            if (j.contains(k)) s[k] = std::move(j[k]);
        }
        eyes.push_back(std::move(s));
    }
    const std::string csv = eyes_csv(eyes, files, o.type, groups);
    if (o.out.empty()) {
        std::cout << csv;
    } else {
        io::write_text_atomically(o.out, csv);
    }
}

}  // namespace

void add_merge_command(CLI::App& app, RunContext& /*ctx*/) {
    auto opts = std::make_shared<MergeOptions>();
    CLI::App* cmd = app.add_subcommand(
        "merge",
        "Build eyes.csv (subject_id, eye, visit_date, scan_type, file, sha256, group, then every "
        "parameter; rows sorted by subject_id, eye, visit_date, file) from per-eye JSON results "
        "of `octshape macula -o` or OUTDIR/eyes of a cohort (docs/cohort.md)");
    cmd->add_option("inputs", opts->inputs, "Per-eye JSON files or folders holding them")
        ->required();
    cmd->add_option("-o,--output", opts->out, "Write the CSV here (default: stdout)");
    cmd->add_option("--groups", opts->groups,
                    "Group column from a CSV with header subject_id,group or file,group");
    cmd->add_option("--type", opts->type,
                    "Which eyes: macula (the eyes.csv table) or onh (eyes_onh.csv)")
        ->capture_default_str();
    cmd->callback([opts] { run(*opts); });
}

}  // namespace octshape::app
