// `octshape onh FILE [-o eye.json] [--csv eye.csv] [--qc DIR] [--ilm SOURCE] [--bmo FILE.csv]
// [--mesh-out DIR]`: the optic nerve head analysis (SPEC §5, docs/algorithms/onh.md); outputs
// documented in docs/outputs.md.

#include "octshape/retina/onh.h"

#include <spdlog/spdlog.h>

#include <filesystem>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>

#include "commands/command.h"
#include "commands/eye_output.h"
#include "commands/onh_qc.h"
#include "octshape/io/error.h"
#include "octshape/io/mesh_io.h"
#include "octshape/io/scan_reader.h"
#include "octshape/io/sha256.h"
#include "octshape/retina/bmo.h"
#include "octshape/retina/onh_report.h"

namespace octshape::app {
namespace {

struct OnhOptions {
    std::string file;
    std::string json_out;
    std::string csv_out;
    std::string qc_dir;
    std::string ilm = "levelset";
    std::string bmo_file;
    std::string mesh_dir;
    std::string mesh_format = "vtp";
    retina::OnhParams params;
};

// DIR/STEM_ilm.EXT (per-face height above the RPE, region bits, signed projected area, local
// ENVT strength) and DIR/STEM_rpe.EXT (per-face: 1 where a corner was filled).
void write_meshes(const retina::OnhResult& r, const OnhOptions& o, const std::string& stem) {
    std::error_code ec;
    std::filesystem::create_directories(o.mesh_dir, ec);
    if (ec) throw OutputError(o.mesh_dir, "cannot create the mesh directory: " + ec.message());
    const std::filesystem::path d(o.mesh_dir);
    Eigen::VectorXd region(r.ilm_F.rows());
    for (Eigen::Index f = 0; f < region.size(); ++f) {
        region(f) = r.face_region[static_cast<std::size_t>(f)];
    }
    io::FaceScalars ilm{{"height_above_rpe_mm", r.face_height_mm},
                        {"region", region},
                        {"signed_projected_area_mm2", r.face_projected_area_mm2}};
    if (r.face_envt_strength.size() == r.ilm_F.rows()) {
        ilm.emplace_back("envt_strength", r.face_envt_strength);
    }
    io::write_mesh(d / (stem + "_ilm." + o.mesh_format), r.ilm_V, r.ilm_F, ilm);
    Eigen::VectorXd filled(r.rpe_F.rows());
    for (Eigen::Index f = 0; f < r.rpe_F.rows(); ++f) {
        bool any = false;
        for (int k = 0; k < 3; ++k)
            any = any || r.rpe.filled[static_cast<std::size_t>(r.rpe_F(f, k))];
        filled(f) = any ? 1.0 : 0.0;
    }
    io::write_mesh(d / (stem + "_rpe." + o.mesh_format), r.rpe_V, r.rpe_F, {{"filled", filled}});
}

void run(OnhOptions& o) {
    o.params.local_features = !o.mesh_dir.empty();  // the ENVT map is a mesh scalar only
    o.params.validate();
    const retina::IlmSource source = retina::ilm_source_from_string(o.ilm);
    if (o.mesh_format != "vtp" && o.mesh_format != "ply") {
        throw UsageError("--mesh-format must be vtp or ply");
    }
    io::ReadOptions read;
    // Pixels: for an ILM source that segments them, and for the B-scans of the QC pictures.
    read.pixels = retina::ilm_needs_pixels(source) || !o.qc_dir.empty();
    const io::Scan scan = io::read_scan(o.file, read);
    try {
        retina::require_onh_volume(scan);
    } catch (const AnalysisError& e) {
        throw AnalysisError(o.file + ": " + e.what());  // one line naming the file
    }
    const std::string sha = io::sha256_file(o.file);
    std::optional<std::vector<retina::BmoPoint>> bmo;
    if (!o.bmo_file.empty()) bmo = retina::read_bmo_csv(o.bmo_file, scan.meta, scan.num_bscans());
    const retina::IlmSurface ilm = retina::build_ilm_surface(scan, source);
    const retina::OnhResult r = retina::analyse_onh(scan, ilm, o.params, bmo);
    for (const auto& f : r.qc_flags) spdlog::warn("{}: QC: {}", o.file, f);
    for (const auto& n : r.notes) spdlog::info("{}: {}", o.file, n);

    nlohmann::ordered_json j = eye_json_preamble("onh", o.file, sha, scan);
    const nlohmann::ordered_json body = retina::onh_json(r, o.params);
    for (const auto& [k, v] : body.items()) j[k] = v;
    if (!o.bmo_file.empty()) j["options"]["bmo_file"] = o.bmo_file;
    std::vector<std::string> header = eye_csv_header();
    std::vector<std::string> row = eye_csv_values(o.file, sha, scan);
    for (auto& h : retina::onh_csv_header()) header.push_back(std::move(h));
    for (auto& v : retina::onh_csv_values(r)) row.push_back(std::move(v));

    const std::string stem = std::filesystem::path(o.file).stem().string();
    if (!o.qc_dir.empty()) write_onh_qc(scan, r, o.params, o.qc_dir, stem);
    if (!o.mesh_dir.empty()) write_meshes(r, o, stem);
    publish_eye_outputs(o.json_out, o.csv_out, j, header, row);
    spdlog::info(
        "{}: {} eye, ILM {}, BMO area {:.4f} mm2, cup {:.4f} mm3, CONHT {:.4f} mm, "
        "MRW {:.4f} mm",
        o.file, r.eye, r.ilm_source, r.ellipse.area_mm2, r.cup_volume_mm3, r.conht_mm,
        r.mrw_mean_mm);
}

}  // namespace

void add_onh_command(CLI::App& app, RunContext& /*ctx*/) {
    auto opts = std::make_shared<OnhOptions>();
    CLI::App* cmd = app.add_subcommand(
        "onh",
        "Optic nerve head analysis (thesis 8.1): BMO ellipse and area, cup/BMO/total/annular "
        "volumes, CONHT, bending energy, BMO-MRW (mean, clock-hour sectors, area). Needs a "
        "volume scan");
    cmd->add_option("file", opts->file, "A Spectralis .vol or Heidelberg XML volume export")
        ->required();
    cmd->add_option("-o,--output", opts->json_out,
                    "Write the per-eye JSON here (default: print it on stdout)");
    cmd->add_option("--csv", opts->csv_out, "Write one CSV row (with header) here");
    cmd->add_option("--qc", opts->qc_dir,
                    "Write QC pictures here: STEM_enface.png (height map, BMO points, ellipse, "
                    "disc), STEM_bscans.png (B-scans through the disc, ILM used vs device ILM, "
                    "MRW vectors), STEM_mrw.png (MRW against the anatomical angle)");
    cmd->add_option("--ilm", opts->ilm,
                    "ILM surface: levelset (3-D Chan-Vese level set on the B-scans, marching "
                    "cubes, RoFi; follows overhangs) or device (the device ILM as a graph mesh)")
        ->capture_default_str();
    cmd->add_option("--bmo", opts->bmo_file,
                    "BMO points from a CSV file (header x_mm,y_mm,z_mm or ascan,bscan,depth_px; "
                    "docs/algorithms/onh.md) instead of the automatic detection");
    cmd->add_option("--mesh-out", opts->mesh_dir,
                    "Write STEM_ilm and STEM_rpe surfaces here with per-face scalars");
    cmd->add_option("--mesh-format", opts->mesh_format, "Mesh file format: vtp or ply")
        ->capture_default_str();
    auto& p = opts->params;
    cmd->add_option("--bmo-points", p.bmo_points,
                    "Resampled BMO ellipse points (uniform in the parameter angle)")
        ->capture_default_str();
    cmd->add_option("--disc-radius-mm", p.disc_radius_mm,
                    "Radius of the total-volume disc around the BMO centre (mm)")
        ->capture_default_str();
    cmd->add_option("--min-gap-area-mm2", p.detection.min_gap_area_mm2,
                    "Smallest BM gap accepted as the disc by the automatic BMO detection (mm2)")
        ->capture_default_str();
    cmd->callback([opts] { run(*opts); });
}

}  // namespace octshape::app
