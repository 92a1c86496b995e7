// `octshape macula FILE [-o eye.json] [--csv eye.csv] [options]`: the CuBe fovea analysis
// (docs/algorithms/cube.md); outputs documented in docs/outputs.md. The per-eye work is
// analyse_macula_eye (commands/macula_eye.h), shared with `octshape cohort`.

#include <CLI/CLI.hpp>
#include <memory>
#include <nlohmann/json.hpp>

#include "commands/command.h"
#include "commands/eye_output.h"
#include "commands/eye_record.h"
#include "commands/macula_eye.h"
#include "octshape/io/atomic_file.h"
#include "octshape/qc/names.h"

namespace octshape::app {
namespace {

struct MaculaOptions {
    std::string file;
    std::string json_out;
    std::string csv_out;
    MaculaEyeOptions eye;
    SubjectOptions subjects;
    std::string eye_key_file;
};

void run(const MaculaOptions& o) {
    check_eye_outputs(o.json_out, o.csv_out, o.eye.qc_dir, "");  // before the analysis
    // A failed run takes back what it published (the QC pictures, the CSV).
    io::OutputJournal journal;
    const SubjectSource subjects = SubjectSource::from_options(o.subjects);
    if (!o.eye_key_file.empty()) set_eye_key_secret(read_key_file(o.eye_key_file));
    MaculaEyeOptions eye = o.eye;
    eye.qc_stem = output_stem(o.json_out, o.csv_out);  // never the input's (patient's) name
    const MaculaEye r = analyse_macula_eye(o.file, eye, subjects);
    publish_eye_outputs(o.json_out, o.csv_out, r.json, r.csv_header, r.csv_row);
    journal.commit();
}

}  // namespace

void add_macula_command(CLI::App& app, RunContext& /*ctx*/) {
    auto opts = std::make_shared<MaculaOptions>();
    CLI::App* cmd = app.add_subcommand(
        "macula",
        "CuBe fovea analysis (cubic Bezier model, thesis 7.1-7.3): CFT, rim, pit, slope, disks, "
        "volumes. A volume scan gives the 3-D analysis, a radial scan (lines through one "
        "point) the same from its lines, a line through the fovea the 2-D one");
    cmd->add_option("file", opts->file,
                    "A Spectralis .vol, Heidelberg XML export, Topcon .fda/.fds or Iowa "
                    "surfaces XML")
        ->required();
    cmd->add_option("-o,--output", opts->json_out,
                    "Write the per-eye JSON here (default: print it on stdout)");
    cmd->add_option("--csv", opts->csv_out, "Write one CSV row (with header) here");
    cmd->add_option("--qc", opts->eye.qc_dir,
                    "Write QC pictures here: " + qc::help_list(retina::ScanType::kMacula) +
                        "; STEM = the -o file's stem, else --csv's, else 'eye'");
    cmd->add_flag("--record-paths", opts->eye.record_paths,
                  "Also write the input's path into the JSON and CSV (identifying: export and "
                  "folder names often hold the patient's name; by default the SHA-256 "
                  "identifies the input)");

    add_macula_analysis_options(cmd, opts->eye);
    add_segmentation_options(cmd, opts->eye.segmentation);
    cmd->add_flag_callback(
        "--no-type-check", [opts] { opts->eye.check_scan_type = false; },
        "Analyse the scan even if it looks like an optic nerve head volume (a long BM "
                  "gap in several B-scans: docs/cohort.md, Classifier)");
    add_subject_options(cmd, opts->subjects);
    add_eye_key_option(cmd, opts->eye_key_file);
    cmd->callback([opts] { run(*opts); });
}

}  // namespace octshape::app
