// `octshape onh FILE [-o eye.json] [--csv eye.csv] [--qc DIR] [--ilm SOURCE] [--bmo FILE.csv]
// [--mesh-out DIR]`: the optic nerve head analysis (docs/algorithms/onh.md); outputs
// documented in docs/outputs.md. The per-eye work is analyse_onh_eye (commands/onh_eye.h),
// shared with `octshape cohort`.

#include <CLI/CLI.hpp>
#include <memory>
#include <string>

#include "commands/command.h"
#include "commands/eye_output.h"
#include "commands/eye_record.h"
#include "commands/onh_eye.h"
#include "octshape/io/atomic_file.h"
#include "octshape/qc/names.h"

namespace octshape::app {
namespace {

struct OnhOptions {
    std::string file;
    std::string json_out;
    std::string csv_out;
    OnhEyeOptions eye;
    SubjectOptions subjects;
    std::string eye_key_file;
};

void run(const OnhOptions& o) {
    check_eye_outputs(o.json_out, o.csv_out, o.eye.qc_dir, o.eye.mesh_dir);  // before the analysis
    // A failed run takes back what it published (pictures, meshes, the CSV).
    io::OutputJournal journal;
    const SubjectSource subjects = SubjectSource::from_options(o.subjects);
    if (!o.eye_key_file.empty()) set_eye_key_secret(read_key_file(o.eye_key_file));
    const FileFacts facts = file_facts(o.file);  // before reading: a missing file says so
    OnhEyeOptions eye = o.eye;
    eye.qc_stem = output_stem(o.json_out, o.csv_out);  // never the input's (patient's) name
    const EyeResult r = analyse_onh_eye(o.file, facts, eye, subjects);
    publish_eye_outputs(o.json_out, o.csv_out, r.json, r.csv_header, r.csv_row);
    journal.commit();
}

}  // namespace

void add_onh_command(CLI::App& app, RunContext& /*ctx*/) {
    auto opts = std::make_shared<OnhOptions>();
    CLI::App* cmd = app.add_subcommand(
        "onh",
        "Optic nerve head analysis (thesis 8.1): BMO ellipse and area, cup/BMO/total/annular "
        "volumes, CONHT, bending energy, BMO-MRW (mean, clock-hour sectors, area). Needs a "
        "volume scan or a radial scan (a radial scan also gives the BMO-MRW in the B-scan "
        "planes; both ILM sources work on both)");
    cmd->add_option("file", opts->file,
                    "A Spectralis .vol or Heidelberg XML volume or radial export")
        ->required();
    cmd->add_option("-o,--output", opts->json_out,
                    "Write the per-eye JSON here (default: print it on stdout)");
    cmd->add_option("--csv", opts->csv_out, "Write one CSV row (with header) here");
    cmd->add_option("--qc", opts->eye.qc_dir,
                    "Write QC pictures here: " + qc::help_list(retina::ScanType::kOnh) +
                        "; STEM = the -o file's stem, else --csv's, else 'eye'");
    cmd->add_flag("--record-paths", opts->eye.record_paths,
                  "Also write the input's path into the JSON and CSV (identifying: export and "
                  "folder names often hold the patient's name; by default the SHA-256 "
                  "identifies the input)");

    cmd->add_option("--mesh-out", opts->eye.mesh_dir,
                    "Write STEM_ilm and STEM_rpe surfaces here with per-face scalars");
    cmd->add_option("--mesh-format", opts->eye.mesh_format, "Mesh file format: vtp or ply")
        ->capture_default_str();
    add_onh_analysis_options(cmd, opts->eye);
    add_segmentation_options(cmd, opts->eye.segmentation);
    add_subject_options(cmd, opts->subjects);
    add_eye_key_option(cmd, opts->eye_key_file);
    cmd->callback([opts] { run(*opts); });
}

}  // namespace octshape::app
