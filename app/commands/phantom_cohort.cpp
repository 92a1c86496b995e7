// `octshape phantom cohort -o DIR --subjects N [--seed S] ...`: a synthetic macula cohort with a
// known group effect (docs/phantoms.md, "Cohort phantom"). Writes
//   DIR/scans/<subject>_<eye>_<k>.vol   the exports (fake patient IDs and visit dates)
//   DIR/truth/<same stem>.truth.json    each scan's true CuBe parameters
//   DIR/subjects.csv                    patient_id,subject_id  (cohort --subjects)
//   DIR/groups.csv                      subject_id,group       (cohort --groups)
//   DIR/groups_by_file.csv              file,group
//   DIR/expected.csv                    parameter,expected (effect | null) for scripts
//   DIR/manifest.json                   design, effects, asserted nulls, true shape variables

#include "octshape/retina/phantom_cohort.h"

#include <CLI/CLI.hpp>
#include <spdlog/spdlog.h>

#include <filesystem>
#include <memory>
#include <string>

#include "commands/command.h"
#include "octshape/io/atomic_file.h"
#include "octshape/error.h"
#include "octshape/io/vol.h"

namespace octshape::app {
namespace {

struct CohortOptions {
    retina::CohortPhantomParams params;
    std::string output;
    double effect_um = 25.0;
    double subject_sd_um = 12.0;
};

void make_dir(const std::filesystem::path& d) {
    std::error_code ec;
    std::filesystem::create_directories(d, ec);
    if (ec) throw OutputError(d.string(), ec.message());
}

void run(CohortOptions& o) {
    o.params.effect_mm = o.effect_um * 1e-3;
    o.params.subject_sd_mm = o.subject_sd_um * 1e-3;
    const retina::CohortPlan plan = retina::plan_macula_cohort(o.params);
    const std::filesystem::path dir(o.output);
    make_dir(dir / "scans");
    make_dir(dir / "truth");
    const retina::MaculaTruthOptions truth_options;
    std::string subjects = "patient_id,subject_id\n";
    std::string groups = "subject_id,group\n";
    std::string groups_by_file = "file,group\n";
    for (const auto& s : plan.scans) {
        retina::MaculaPhantom ph = retina::make_macula_phantom(s.params, truth_options);
        retina::apply_cohort_identity(s, ph.scan);
        const std::filesystem::path vol = dir / "scans" / s.file_name;
        std::filesystem::path truth = dir / "truth" / s.file_name;
        truth.replace_extension(".truth.json");
        io::write_vol_file(ph.scan, vol.string());
        io::write_text_atomically(
            truth.string(),
            retina::macula_truth_json(ph.truth, s.params, truth_options).dump(2) + "\n");
        groups_by_file += s.file_name + "," + s.group + "\n";
        if (s.params.eye == io::Laterality::kOD && s.scan_index == 1) {
            subjects += s.patient_id + "," + s.subject_id + "\n";
            groups += s.subject_id + "," + s.group + "\n";
        }
    }
    io::write_text_atomically((dir / "subjects.csv").string(), subjects);
    io::write_text_atomically((dir / "groups.csv").string(), groups);
    io::write_text_atomically((dir / "groups_by_file.csv").string(), groups_by_file);
    std::string expected = "parameter,expected\n";
    for (const auto& e : plan.manifest["effects"].items()) expected += e.key() + ",effect\n";
    for (const auto& name : plan.manifest["nulls"]) {
        expected += name.get<std::string>() + ",null\n";
    }
    io::write_text_atomically((dir / "expected.csv").string(), expected);
    io::write_text_atomically((dir / "manifest.json").string(), plan.manifest.dump(2) + "\n");
    spdlog::info("wrote {} scans of {} subjects under {}", plan.scans.size(), o.params.subjects,
                 dir.string());
}

}  // namespace

void add_phantom_cohort_command(CLI::App& parent, RunContext& /*ctx*/) {
    auto opts = std::make_shared<CohortOptions>();
    auto& p = opts->params;
    CLI::App* cmd = parent.add_subcommand(
        "cohort",
        "A synthetic macula cohort: N subjects x 2 eyes in groups control/case with a known "
        "group effect on CFT, rim height and rim volumes and none on pit depth and slope "
        "(matched pairs); re-scans; fake patient IDs; groups and subjects CSVs; manifest "
        "(docs/phantoms.md)");
    cmd->add_option("-o,--output", opts->output, "Output directory")->required();
    cmd->add_option("--subjects", p.subjects, "Number of subjects N (alternately control, case)")
        ->capture_default_str();
    cmd->add_option("--seed", p.seed, "Seed of every random choice")->capture_default_str();
    cmd->add_option("--effect-um", opts->effect_um, "Case minus control thickness offset (um)")
        ->capture_default_str();
    cmd->add_option("--subject-sd-um", opts->subject_sd_um,
                    "Between-subject SD of the thickness offset (um)")
        ->capture_default_str();
    cmd->add_option("--retest-subjects", p.retest_subjects,
                    "Subjects whose two eyes are scanned twice (the first ones)")
        ->capture_default_str();
    cmd->add_option("--noise-um", p.noise_um, "Segmentation noise SD (um)")->capture_default_str();
    cmd->add_option("--bscans", p.num_bscans, "B-scans per volume")->capture_default_str();
    cmd->add_option("--ascans", p.size_x, "A-scans per B-scan")->capture_default_str();
    cmd->add_flag("--pixels", p.pixels, "Render B-scan pixels (slower; default: no pixel data)");
    cmd->callback([opts] { run(*opts); });
}

}  // namespace octshape::app
