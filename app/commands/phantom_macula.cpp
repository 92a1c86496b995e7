// `octshape phantom macula`: a synthetic Spectralis macula export and its true CuBe parameters
// (docs/phantoms.md, "Macula phantoms").

#include <CLI/CLI.hpp>
#include <cmath>
#include <filesystem>
#include <string>

#include <spdlog/spdlog.h>

#include "commands/command.h"
#include "commands/phantom_options.h"
#include "octshape/io/atomic_file.h"
#include "octshape/error.h"
#include "octshape/io/topcon.h"
#include "octshape/io/vol.h"
#include "octshape/retina/phantom_macula.h"

namespace octshape::app {
namespace {

struct MaculaOptions {
    retina::MaculaPhantomParams params;
    retina::MaculaTruthOptions truth;
    std::string output;
    std::string family = "bezier";
    std::string eye = "OD";
    std::string pattern = "volume";
    std::string bscan_direction = "horizontal";
    std::string format = "vol";  // vol | fda
    bool no_pixels = false;
    double tau_um = retina::MaculaTruthOptions{}.tau_mm * 1e3;  // the truth's default, in um
    double crossing_offset_um = 0.0;
    double crossing_offset_deg = 0.0;
};

// FILE.vol -> FILE.truth.json
std::string truth_path(const std::string& vol_path) {
    std::filesystem::path p(vol_path);
    p.replace_extension(".truth.json");
    return p.string();
}

void run(MaculaOptions& o) {
    if (std::filesystem::path(o.output).extension() != "." + o.format) {
        throw UsageError(o.output + ": the output of phantom macula --format " + o.format +
                         " must end in ." + o.format);
    }
    if (o.format == "fda" && o.pattern != "volume") {
        throw UsageError("phantom macula --format fda writes volumes only (a Topcon .fda holds "
                         "no radial or single-line pattern octshape reads)");
    }
    if (o.bscan_direction == "vertical" && (o.pattern != "volume" || o.format != "vol")) {
        throw UsageError("phantom macula --bscan-direction vertical makes .vol volumes only "
                         "(--pattern volume --format vol)");
    }
    retina::MaculaPhantomParams& p = o.params;
    p.vertical = o.bscan_direction == "vertical";
    p.family = o.family == "scheibe" ? retina::MaculaFamily::kScheibe
                                     : retina::MaculaFamily::kBezier;
    p.eye = o.eye == "OS" ? io::Laterality::kOS : io::Laterality::kOD;
    p.line = o.pattern == "line";
    p.radial = o.pattern == "radial";
    if (p.radial && (o.crossing_offset_um != 0.0)) {
        // The crossing offset along an anatomical direction: fovea minus crossing, grid mm
        // (grid +x = SLO +x, nasal for OD, temporal for OS; +y superior).
        const double th = o.crossing_offset_deg * 3.14159265358979323846 / 180.0;
        const double nasal_x = p.eye == io::Laterality::kOS ? -1.0 : 1.0;
        p.fovea_dx_mm = 1e-3 * o.crossing_offset_um * std::cos(th) * nasal_x;
        p.fovea_dy_mm = 1e-3 * o.crossing_offset_um * std::sin(th);
    }
    p.pixels = !o.no_pixels && o.format != "fda";  // a .fda written here holds no pixels
    o.truth.tau_mm = o.tau_um * 1e-3;
    const retina::MaculaPhantom ph = retina::make_macula_phantom(p, o.truth);
    const std::string json = retina::macula_truth_json(ph.truth, p, o.truth).dump(2) + "\n";
    const std::string truth = truth_path(o.output);
    if (o.format == "fda") {
        io::write_topcon_file(ph.scan, o.output);
    } else {
        io::write_vol_file(ph.scan, o.output);
    }
    try {
        io::write_text_atomically(truth, json);
    } catch (...) {
        std::error_code ec;
        std::filesystem::remove(o.output, ec);  // never leave a scan without its truth
        throw;
    }
    spdlog::info("wrote {} ({} B-scans x {} A-scans x {} px, {}) and {}", o.output,
                 ph.scan.num_bscans(), ph.scan.meta.size_x, ph.scan.meta.size_z,
                 p.pixels ? "pixels" : "no pixels", truth);
}

}  // namespace

void add_phantom_macula_command(CLI::App& parent, RunContext& /*ctx*/) {
    auto opts = std::make_shared<MaculaOptions>();
    CLI::App* cmd = parent.add_subcommand(
        "macula",
        "Spectralis-style macula export (.vol) plus FILE.truth.json with the true CuBe "
        "parameters (docs/algorithms/cube.md) computed from the generating surface");
    auto& p = opts->params;
    cmd->add_option("-o,--output", opts->output,
                    "Output FILE.vol or FILE.fda (FILE.truth.json beside it)")
        ->required();
    cmd->add_option("--format", opts->format,
                    "vol (Spectralis .vol with pixels) or fda (Topcon .fda: the ILM and BM as "
                    "the device's contours, whole pixels, no pixels; volumes only)")
        ->check(CLI::IsMember({"vol", "fda"}))
        ->capture_default_str();
    cmd->add_option("--family", opts->family,
                    "Thickness profiles: bezier (exactly CuBe) or scheibe (not representable)")
        ->check(CLI::IsMember({"bezier", "scheibe"}))
        ->capture_default_str();
    cmd->add_flag("--flat", p.flat, "Flat-bottomed pits");
    cmd->add_option("--eye", opts->eye, "Laterality")
        ->check(CLI::IsMember({"OD", "OS"}))
        ->capture_default_str();
    cmd->add_option("--pattern", opts->pattern,
                    "volume, line (one horizontal B-scan through the fovea) or radial (B-scans "
                    "rotated about one point, ScanPattern 5)")
        ->check(CLI::IsMember({"volume", "line", "radial"}))
        ->capture_default_str();
    cmd->add_option("--bscan-direction", opts->bscan_direction,
                    "volume: horizontal B-scans (the first one inferior) or vertical (the first "
                    "one leftmost on the SLO, A-scans from superior to inferior): the same eye "
                    "scanned the other way")
        ->check(CLI::IsMember({"horizontal", "vertical"}))
        ->capture_default_str();
    cmd->add_option("--lines", p.radial_lines,
                    "radial: number of B-scans (lines), 180 / lines deg apart")
        ->capture_default_str();
    cmd->add_option("--line-length-mm", p.line_length_mm, "radial: length of each line (mm)")
        ->capture_default_str();
    cmd->add_option("--crossing-offset-um", opts->crossing_offset_um,
                    "radial: true fovea minus the lines' crossing (um; replaces --fovea-dx/dy)")
        ->capture_default_str();
    cmd->add_option("--crossing-offset-deg", opts->crossing_offset_deg,
                    "radial: direction of that offset (anatomical: 0 nasal, 90 superior)")
        ->capture_default_str();
    cmd->add_option("--bscans", p.num_bscans,
                    "B-scans over the 7.5 mm field (61, 97, 193 on the device)")
        ->capture_default_str();
    cmd->add_option("--ascans", p.size_x, "A-scans per B-scan over the 8.98 mm field")
        ->capture_default_str();
    cmd->add_option("--depth", p.size_z, "Pixels per A-scan")->capture_default_str();
    cmd->add_option("--scale-x", p.scale_x_mm, "mm per A-scan (default: 8.96623 / (ascans - 1))");
    cmd->add_option("--distance", p.distance_mm,
                    "mm between B-scans (default: 7.5 / (bscans - 1))");
    cmd->add_option("--scale-z", p.scale_z_mm, "mm per pixel in depth")->capture_default_str();
    cmd->add_option("--fovea-dx", p.fovea_dx_mm, "True fovea centre minus scan centre, grid x mm")
        ->capture_default_str();
    cmd->add_option("--fovea-dy", p.fovea_dy_mm, "True fovea centre minus scan centre, grid y mm")
        ->capture_default_str();
    cmd->add_option("--grid-dx", p.grid_hint_dx_mm,
                    "Device ETDRS grid centre minus true fovea centre, grid x mm")
        ->capture_default_str();
    cmd->add_option("--grid-dy", p.grid_hint_dy_mm,
                    "Device ETDRS grid centre minus true fovea centre, grid y mm")
        ->capture_default_str();
    cmd->add_option("--wall-radius-mm", p.wall_radius_mm,
                    "Apparent eye-wall radius in the image (paraboloid; 0 = flat)")
        ->capture_default_str();
    cmd->add_option("--rotation-deg", p.rotation_deg,
                    "Eye rotated about the fovea against the scan grid (anatomical deg)")
        ->capture_default_str();
    cmd->add_option("--radial-scale", p.radial_scale,
                    "Every radius of the pit profile multiplied by this (0.7-1.3)")
        ->capture_default_str();
    cmd->add_option("--tilt-x", p.tilt_x, "BM slope along grid x (mm/mm)")->capture_default_str();
    cmd->add_option("--tilt-y", p.tilt_y, "BM slope along grid y (mm/mm)")->capture_default_str();
    cmd->add_option("--noise-um", p.noise_um, "Gaussian segmentation noise SD on ILM and BM (um)")
        ->capture_default_str();
    cmd->add_option("--missing", p.missing_fraction,
                    "Fraction of A-scans with ILM and BM missing (edge blocks + random)")
        ->capture_default_str();
    cmd->add_option("--vessels", p.vessels, "Vessel-like bands raising the ILM by 3-8 um")
        ->capture_default_str();
    add_acquisition_options(cmd, p.artefacts);
    cmd->add_flag("--no-pixels", opts->no_pixels,
                  "Write B-scan pixels as 'no data' (FLT_MAX): faster, for analysis-only tests");
    cmd->add_option("--seed", p.seed, "Seed of every random choice")->capture_default_str();
    cmd->add_option("--speckle-looks", p.speckle.looks,
                    "Speckle Gamma shape (1 = fully developed; ART averaging raises it)")
        ->capture_default_str();
    add_speckle_grain_options(cmd, p.speckle.axial_half_width_px,
                              p.speckle.lateral_half_width_px);
    cmd->add_option("--half-lines", opts->truth.num_half_lines, "Truth: radial half-lines n")
        ->capture_default_str();
    cmd->add_option("--radius-mm", opts->truth.radius_mm, "Truth: radius R")->capture_default_str();
    cmd->add_option("--tau-um", opts->tau_um, "Truth: pit-flat threshold tau")
        ->capture_default_str();
    cmd->add_option("--inner-radius-mm", opts->truth.inner_radius_mm,
                    "Truth: inner-rim radius r_u")
        ->capture_default_str();
    cmd->callback([opts] { run(*opts); });
}

}  // namespace octshape::app
