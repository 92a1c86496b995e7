// `octshape macula FILE [-o eye.json] [--csv eye.csv] [options]`: the CuBe fovea analysis
// (SPEC §4, docs/algorithms/cube.md); outputs documented in docs/outputs.md. The per-eye work is
// analyse_macula_eye (commands/macula_eye.h), shared with `octshape cohort`.

#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>

#include "commands/command.h"
#include "commands/eye_record.h"
#include "commands/macula_eye.h"
#include "octshape/io/atomic_file.h"

namespace octshape::app {
namespace {

struct MaculaOptions {
    std::string file;
    std::string json_out;
    std::string csv_out;
    MaculaEyeOptions eye;
    SubjectOptions subjects;
};

void run(const MaculaOptions& o) {
    const SubjectSource subjects = SubjectSource::from_options(o.subjects);
    const MaculaEye r = analyse_macula_eye(o.file, o.eye, subjects);
    // Each file is written atomically (temporary file + rename): none appears half-written.
    if (!o.csv_out.empty()) {
        io::write_text_atomically(o.csv_out, csv_line(r.csv_header) + csv_line(r.csv_row));
    }
    if (!o.json_out.empty()) io::write_text_atomically(o.json_out, r.json.dump(2) + "\n");
    if (o.json_out.empty() && o.csv_out.empty()) std::cout << r.json.dump(2) << '\n';
}

}  // namespace

void add_macula_command(CLI::App& app, RunContext& /*ctx*/) {
    auto opts = std::make_shared<MaculaOptions>();
    CLI::App* cmd = app.add_subcommand(
        "macula",
        "CuBe fovea analysis (cubic Bezier model, thesis 7.1-7.3): CFT, rim, pit, slope, disks, "
        "volumes. A volume scan gives the 3-D analysis, a line through the fovea the 2-D one");
    cmd->add_option("file", opts->file, "A Spectralis .vol or Heidelberg XML export")->required();
    cmd->add_option("-o,--output", opts->json_out,
                    "Write the per-eye JSON here (default: print it on stdout)");
    cmd->add_option("--csv", opts->csv_out, "Write one CSV row (with header) here");
    cmd->add_option("--qc", opts->eye.qc_dir,
                    "Write QC pictures here: STEM_thickness.png (map, centre, rim/slope/pit-flat "
                    "disks) and STEM_profiles.png (half-lines with their fitted Beziers)");
    add_macula_analysis_options(cmd, opts->eye);
    add_subject_options(cmd, opts->subjects);
    cmd->callback([opts] { run(*opts); });
}

}  // namespace octshape::app
