// `octshape macula FILE [-o eye.json] [--csv eye.csv] [options]`: the CuBe fovea analysis
// (SPEC §4, docs/algorithms/cube.md); outputs documented in docs/outputs.md.

#include <spdlog/spdlog.h>

#include <filesystem>
#include <memory>
#include <nlohmann/json.hpp>

#include "commands/command.h"
#include "commands/eye_output.h"
#include "commands/macula_qc.h"
#include "octshape/io/scan_reader.h"
#include "octshape/io/sha256.h"
#include "octshape/retina/cube.h"
#include "octshape/retina/cube_report.h"

namespace octshape::app {
namespace {

struct MaculaOptions {
    std::string file;
    std::string json_out;
    std::string csv_out;
    std::string qc_dir;
    retina::CubeParams params;
    double tau_um = 5.0;
};

void run(MaculaOptions& o) {
    o.params.tau_mm = o.tau_um * 1e-3;
    o.params.validate();
    const io::Scan scan = io::read_scan(o.file);
    const std::string sha = io::sha256_file(o.file);
    const retina::CubeResult r = retina::analyse_macula(scan, o.params);
    for (const auto& f : r.qc_flags) spdlog::warn("{}: QC: {}", o.file, f);
    for (const auto& n : r.notes) spdlog::info("{}: {}", o.file, n);

    nlohmann::ordered_json j = eye_json_preamble("macula", o.file, sha, scan);
    const auto cube = retina::cube_json(r, o.params);
    for (const auto& [k, v] : cube.items()) j[k] = v;
    const std::string eye(io::to_string(scan.meta.laterality));

    std::vector<std::string> header = eye_csv_header();
    std::vector<std::string> row = eye_csv_values(o.file, sha, scan);
    for (auto& h : retina::cube_csv_header()) header.push_back(std::move(h));
    for (auto& v : retina::cube_csv_values(r)) row.push_back(std::move(v));

    if (!o.qc_dir.empty()) {
        write_macula_qc(r, o.qc_dir, std::filesystem::path(o.file).stem().string());
    }
    publish_eye_outputs(o.json_out, o.csv_out, j, header, row);
    spdlog::info("{}: {} eye, CFT {:.4f} mm, rim height {:.4f} mm, RMSE {:.2f} um", o.file, eye,
                 r.cft_mm, r.rim_height_mm, r.rmse_um);
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
    cmd->add_option("--qc", opts->qc_dir,
                    "Write QC pictures here: STEM_thickness.png (map, centre, rim/slope/pit-flat "
                    "disks) and STEM_profiles.png (half-lines with their fitted Beziers)");
    auto& p = opts->params;
    cmd->add_option("--half-lines", p.num_half_lines, "Number of radial half-lines n (even)")
        ->capture_default_str();
    cmd->add_option("--radius-mm", p.radius_mm, "Length R of each half-line (mm)")
        ->capture_default_str();
    cmd->add_option("--spacing-mm", p.sample_spacing_mm,
                    "Radial sample spacing (mm); 0 = the scan's ScaleX")
        ->capture_default_str();
    cmd->add_option("--tau-um", opts->tau_um, "Pit-flat threshold above CFT (um)")
        ->capture_default_str();
    cmd->add_option("--inner-radius-mm", p.inner_radius_mm,
                    "Radius r_u of the inner rim volume (mm)")
        ->capture_default_str();
    cmd->add_option("--search-radius-mm", p.search_radius_mm,
                    "Centre search radius around the device fovea centre (mm)")
        ->capture_default_str();
    cmd->callback([opts] { run(*opts); });
}

}  // namespace octshape::app
