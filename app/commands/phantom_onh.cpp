// `octshape phantom onh`: a synthetic Spectralis ONH volume and its truth (docs/phantoms.md).

#include <CLI/CLI.hpp>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include <spdlog/spdlog.h>

#include "commands/command.h"
#include "commands/phantom_options.h"
#include "octshape/io/atomic_file.h"
#include "octshape/error.h"
#include "octshape/io/vol.h"
#include "octshape/retina/phantom_onh.h"

namespace octshape::app {
namespace {

struct PhantomOnhState {
    std::string output;
    std::string truth_path;
    std::string shape = "cupped";
    std::string eye = "OD";
    retina::OnhPhantomParams params;
    retina::OnhTruthOptions truth;
    std::vector<double> bmo_offset_mm;
    std::vector<double> bmo_axes_mm;
    std::vector<double> tilt;
    retina::OnhProfileParams profile;  // values of the profile override options
    std::string pattern = "volume";
};

// FILE.vol -> FILE.truth.json (any other name: NAME.truth.json).
std::string default_truth_path(const std::string& output) {
    std::filesystem::path p(output);
    if (p.extension() == ".vol") p.replace_extension();
    return p.string() + ".truth.json";
}

void run(PhantomOnhState& st, const CLI::App& cmd) {
    const retina::OnhShape shape = st.shape == "swollen"    ? retina::OnhShape::kSwollen
                                   : st.shape == "overhang" ? retina::OnhShape::kOverhang
                                                            : retina::OnhShape::kCupped;
    // Start from the preset of the shape; explicit options override it.
    retina::OnhPhantomParams p = retina::onh_phantom_preset(shape);
    const retina::OnhPhantomParams& given = st.params;
    p.eye = st.eye == "OS" ? io::Laterality::kOS : io::Laterality::kOD;
    p.seed = given.seed;
    p.num_bscans = given.num_bscans;
    p.num_ascans = given.num_ascans;
    p.depth_px = given.depth_px;
    p.field_mm = given.field_mm;
    p.bm_centre_depth_fraction = given.bm_centre_depth_fraction;
    p.bmo_rotation_deg = given.bmo_rotation_deg;
    p.eye_radius_mm = given.eye_radius_mm;
    p.speckle_looks = given.speckle_looks;
    p.speckle_axial_half_width_px = given.speckle_axial_half_width_px;
    p.speckle_lateral_half_width_px = given.speckle_lateral_half_width_px;
    p.radial = st.pattern == "radial";
    p.radial_lines = given.radial_lines;
    p.line_length_mm = given.line_length_mm;
    p.crossing_offset_um = given.crossing_offset_um;
    p.artefacts = given.artefacts;
    if (!st.bmo_offset_mm.empty()) {
        p.bmo_offset_x_mm = st.bmo_offset_mm[0];
        p.bmo_offset_y_mm = st.bmo_offset_mm[1];
    }
    if (!st.bmo_axes_mm.empty()) {
        p.bmo_semi_major_mm = st.bmo_axes_mm[0];
        p.bmo_semi_minor_mm = st.bmo_axes_mm[1];
    }
    if (!st.tilt.empty()) {
        p.tilt_x = st.tilt[0];
        p.tilt_y = st.tilt[1];
    }
    auto set = [&cmd](const char* name, double value, double& target) {
        if (cmd.count(name) > 0) target = value;
    };
    set("--retina-thickness-mm", st.profile.retina_thickness_mm, p.profile.retina_thickness_mm);
    set("--rim-height-mm", st.profile.rim_height_mm, p.profile.rim_height_mm);
    set("--cup-depth-mm", st.profile.cup_depth_mm, p.profile.cup_depth_mm);
    set("--cup-radius", st.profile.cup_radius, p.profile.cup_radius);
    set("--swelling-mm", st.profile.swelling_mm, p.profile.swelling_mm);
    set("--undercut", st.profile.undercut, p.profile.undercut);
    p.validate();

    const std::string truth_path =
        st.truth_path.empty() ? default_truth_path(st.output) : st.truth_path;
    spdlog::info("phantom onh: {} {} disc, {} {} x {} A-scans x {} px",
                 p.eye == io::Laterality::kOS ? "OS" : "OD", retina::to_string(p.shape),
                 p.radial ? p.radial_lines : p.num_bscans,
                 p.radial ? "radial lines" : "B-scans", p.num_ascans, p.depth_px);
    const retina::OnhPhantom phantom = retina::make_onh_phantom(p, st.truth);
    const std::string truth_text =
        retina::onh_truth_to_json(p, st.truth, phantom.truth).dump(2) + "\n";
    io::write_vol_file(phantom.scan, st.output);
    io::write_text_atomically(truth_path, truth_text);
    spdlog::info("wrote {} and {} (truth computed in {:.2f} s)", st.output, truth_path,
                 phantom.truth.seconds);
}

}  // namespace

void add_phantom_onh_command(CLI::App& phantom, RunContext& /*ctx*/) {
    auto st = std::make_shared<PhantomOnhState>();
    const retina::OnhPhantomParams d;
    st->params = d;
    st->profile = d.profile;
    CLI::App* cmd = phantom.add_subcommand(
        "onh",
        "Optic nerve head volume (Spectralis HSF-OCT-103, ScanPattern 3) or radial scan "
        "(--pattern radial, ScanPattern 5) with a curved BM, an elliptical BMO and a cupped, "
        "swollen or overhanging ILM; writes FILE.vol and FILE.truth.json (the true ONH "
        "parameters, docs/phantoms.md)");
    cmd->add_option("-o,--output", st->output, "Output .vol file")->required();
    cmd->add_option("--truth", st->truth_path, "Truth JSON (default: FILE.truth.json)");
    cmd->add_option("--shape", st->shape, "ILM shape")
        ->check(CLI::IsMember({"cupped", "swollen", "overhang"}))
        ->capture_default_str();
    cmd->add_option("--eye", st->eye, "Laterality")
        ->check(CLI::IsMember({"OD", "OS"}))
        ->capture_default_str();
    cmd->add_option("--seed", st->params.seed, "Speckle seed (same seed, same file)")
        ->capture_default_str();
    cmd->add_option("--bscans", st->params.num_bscans, "Number of B-scans")->capture_default_str();
    cmd->add_option("--ascans", st->params.num_ascans, "A-scans per B-scan (radial: per line)")
        ->capture_default_str();
    cmd->add_option("--pattern", st->pattern,
                    "volume, or radial: --lines B-scans through one point, the same eye as the "
                    "volume of the same options")
        ->check(CLI::IsMember({"volume", "radial"}))
        ->capture_default_str();
    cmd->add_option("--lines", st->params.radial_lines, "Radial lines (180 / N deg apart)")
        ->capture_default_str();
    cmd->add_option("--line-length-mm", st->params.line_length_mm, "Length of a radial line")
        ->capture_default_str();
    cmd->add_option("--crossing-offset-um", st->params.crossing_offset_um,
                    "The lines' crossing minus the BMO centre, along grid +x (um)")
        ->capture_default_str();
    cmd->add_option("--depth", st->params.depth_px, "Pixels per A-scan")->capture_default_str();
    cmd->add_option("--field-mm", st->params.field_mm,
                    "Side of the scanned square (ScaleX = field / A-scans, Distance = field / "
                    "(B-scans - 1))")
        ->capture_default_str();
    cmd->add_option("--bm-depth-fraction", st->params.bm_centre_depth_fraction,
                    "Depth of the BM at the BMO centre as a fraction of the image depth")
        ->capture_default_str();
    cmd->add_option("--bmo-offset-mm", st->bmo_offset_mm,
                    "BMO centre minus the field centre, X Y in grid mm (default 0.06 -0.04)")
        ->expected(2);
    cmd->add_option("--bmo-axes-mm", st->bmo_axes_mm,
                    "BMO semi-axes A B in mm, A >= B (default 0.92 0.76)")
        ->expected(2);
    cmd->add_option("--bmo-rotation-deg", st->params.bmo_rotation_deg,
                    "Angle of the BMO major axis from grid +x towards +y")
        ->capture_default_str();
    cmd->add_option("--eye-radius-mm", st->params.eye_radius_mm,
                    "Curvature radius of the BM (eye wall); 0 = flat")
        ->capture_default_str();
    cmd->add_option("--tilt", st->tilt,
                    "BM slopes dz/dx dz/dy at the BMO centre (default 0.03 "
                    "-0.02)")
        ->expected(2);
    cmd->add_option("--speckle-looks", st->params.speckle_looks,
                    "Speckle Gamma shape (more looks = less speckle)")
        ->capture_default_str();
    add_speckle_grain_options(cmd, st->params.speckle_axial_half_width_px,
                              st->params.speckle_lateral_half_width_px);
    cmd->add_option("--retina-thickness-mm", st->profile.retina_thickness_mm,
                    "ILM height above BM far from the disc (preset: 0.30)");
    cmd->add_option("--rim-height-mm", st->profile.rim_height_mm,
                    "Extra rim thickness (preset of the shape)");
    cmd->add_option("--cup-depth-mm", st->profile.cup_depth_mm,
                    "Depth of the cup term at the centre (preset of the shape)");
    cmd->add_option("--cup-radius", st->profile.cup_radius,
                    "Radius of the cup term in BMO radii (preset of the shape)");
    cmd->add_option("--swelling-mm", st->profile.swelling_mm,
                    "Amplitude of the swelling term (preset of the shape)");
    cmd->add_option("--undercut", st->profile.undercut,
                    "Outward push of the cup wall in BMO radii, 0 = none (preset of the shape)");
    add_acquisition_options(cmd, st->params.artefacts);
    cmd->add_option("--mrw-points", st->truth.mrw_points,
                    "BMO points for the MRW truth (uniform in the ellipse parameter angle)")
        ->capture_default_str();
    cmd->callback([st, cmd] { run(*st, *cmd); });
}

}  // namespace octshape::app
