#include "commands/onh_eye.h"

#include <CLI/CLI.hpp>
#include <spdlog/spdlog.h>

#include <filesystem>
#include <optional>
#include <sstream>
#include <vector>

#include "commands/eye_output.h"
#include "commands/mesh_common.h"
#include "octshape/qc/onh.h"
#include "commands/provenance.h"
#include "octshape/error.h"
#include "octshape/io/mesh_io.h"
#include "octshape/io/scan_reader.h"
#include "octshape/retina/bmo.h"
#include "octshape/retina/levelset.h"
#include "octshape/retina/radial_geometry.h"
#include "octshape/retina/scan_type.h"
#include "octshape/io/sha256.h"
#include "octshape/retina/onh_report.h"

namespace octshape::app {
namespace {

// DIR/STEM_ilm.EXT (per-face height above the RPE, region bits, signed projected area, local
// ENVT strength) and DIR/STEM_rpe.EXT (per-face: 1 where a corner was filled).
// `provenance`: io::write_mesh's line (the input, its SHA-256 and the options).
void write_meshes(const retina::OnhResult& r, const OnhEyeOptions& o, const std::string& stem,
                  const std::string& provenance) {
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
    io::write_mesh(d / (stem + "_ilm." + o.mesh_format), r.ilm_V, r.ilm_F, ilm, provenance);
    Eigen::VectorXd filled(r.rpe_F.rows());
    for (Eigen::Index f = 0; f < r.rpe_F.rows(); ++f) {
        bool any = false;
        for (int k = 0; k < 3; ++k)
            any = any || r.rpe.filled[static_cast<std::size_t>(r.rpe_F(f, k))];
        filled(f) = any ? 1.0 : 0.0;
    }
    io::write_mesh(d / (stem + "_rpe." + o.mesh_format), r.rpe_V, r.rpe_F, {{"filled", filled}},
                   provenance);
}

}  // namespace

std::string onh_options_text(const OnhEyeOptions& o) {
    // Every effective parameter: the command-line ones, the BMO file by its SHA-256 (never its
    // path), and the code defaults of the level set and its RoFi smoothing, which the ILM
    // depends on: the fingerprint's parameter text.
    const auto& p = o.params;
    const retina::LevelSetParams ls;
    const retina::ScanTypeParams classifier;
    std::ostringstream s;
    s.precision(17);
    s << std::boolalpha;  // switches as true/false, as the provenance's qc_pictures
    const std::string bmo = o.bmo_file.empty() ? std::string("automatic")
                                                : file_fingerprint(o.bmo_file);
    s << "onh ilm=" << o.ilm << " bmo=" << bmo << " bmo_points=" << p.bmo_points
      << " disc_radius_mm=" << p.disc_radius_mm
      << " min_gap_area_mm2=" << p.detection.min_gap_area_mm2
      << " local_features=" << p.local_features
      << " axial_registration=" << p.axial_registration.enabled
      << " axial_registration_degree=" << p.axial_registration.surface_degree
      << " axial_registration_isotropic_curvature=" << p.axial_registration.isotropic_curvature
      << " lateral_registration=" << p.lateral_registration.enabled
      << " lateral_registration_wavelength_mm=" << p.lateral_registration.smooth_wavelength_mm
      << " lateral_registration_wavelength_bscans=" << p.lateral_registration.smooth_wavelength_bscans
      << " mesh=" << (o.mesh_dir.empty() ? std::string("none") : o.mesh_format);
    s << " levelset(lateral_radius_mm=" << ls.lateral_radius_mm << " margin_mm=" << ls.margin_mm
      << " despeckle_passes=" << ls.despeckle_passes << " mu_mm=" << ls.mu_mm
      << " lambda_vitreous=" << ls.lambda_vitreous << " lambda_tissue=" << ls.lambda_tissue
      << " region_means=" << static_cast<int>(ls.region_means)
      << " hidden_local_level=" << ls.hidden_local_level
      << " open_vitreous_mean=" << ls.open_vitreous_mean
      << " band_layers=" << ls.band_layers << " reinit_interval=" << ls.reinit_interval
      << " cfl=" << ls.cfl << " max_iterations=" << ls.max_iterations
      << " tile_mm=" << ls.tile_mm << " patience=" << ls.patience
      << " slab_bscans=" << ls.slab_bscans << " smooth=" << ls.smooth
      << " leak_fallback=" << ls.leak_fallback << " leak_depth_mm=" << ls.leak_depth_mm << ")";
    const auto& r = ls.rofi;
    s << " rofi(sigma_s=" << r.sigma_s << " lambda_i=" << r.lambda_i
      << " iterations=" << r.iterations << " lambda_decay=" << r.lambda_decay
      << " radius_factor=" << r.radius_factor << " sigma_c_factor=" << r.sigma_c_factor
      << " similarity=" << static_cast<int>(r.similarity)
      << " pair_weights=" << static_cast<int>(r.pair_weights)
      << " fix_boundary=" << r.fix_boundary << " repair_folds=" << r.repair_folds << ")";
    s << " classifier_min_gap_mm=" << classifier.min_gap_mm
      << " classifier_min_bscans=" << classifier.min_bscans << ' '
      << segmentation_options_text(o.segmentation);
    return s.str();
}

void add_onh_analysis_options(CLI::App* cmd, OnhEyeOptions& o, bool per_eye_files) {
    cmd->add_option("--ilm", o.ilm,
                    "ILM surface: levelset (3-D Chan-Vese level set on the B-scans, marching "
                    "cubes, RoFi; follows overhangs) or device (the device ILM as a graph mesh)")
        ->capture_default_str();
    if (per_eye_files) {
        cmd->add_option("--bmo", o.bmo_file,
                        "BMO points from a CSV file (header x_mm,y_mm,z_mm or "
                        "ascan,bscan,depth_px; radial scans: ascan,bscan,depth_px only; "
                        "docs/algorithms/onh.md) instead of the automatic detection");
    }
    auto& p = o.params;
    cmd->add_option("--bmo-points", p.bmo_points,
                    "Resampled BMO ellipse points (uniform in the parameter angle)")
        ->capture_default_str();
    cmd->add_option("--disc-radius-mm", p.disc_radius_mm,
                    "Radius of the total-volume disc around the BMO centre (mm)")
        ->capture_default_str();
    cmd->add_flag_callback(
        "--no-axial-registration", [&p] { p.axial_registration.enabled = false; },
        "Do not remove the axial eye motion between B-scans (estimated from the BM and "
        "reported either way; docs/algorithms/onh.md)");
    cmd->add_flag_callback(
        "--no-lateral-registration", [&p] { p.lateral_registration.enabled = false; },
        "Do not remove the lateral shifts of a volume's B-scans (estimated from the ILM and BM "
        "lines and reported either way; docs/algorithms/onh.md)");
    cmd->add_option("--min-gap-area-mm2", p.detection.min_gap_area_mm2,
                    "Smallest BM gap accepted as the disc by the automatic BMO detection (mm2)")
        ->capture_default_str();
}

EyeResult analyse_onh_eye(const std::string& file,
                          const FileFacts& facts,
                          OnhEyeOptions o,
                          const SubjectSource& subjects) {
    Provenance prov("onh");
    o.params.local_features = !o.mesh_dir.empty();  // the ENVT map is a mesh scalar only
    o.params.validate();
    const retina::IlmSource source = retina::ilm_source_from_string(o.ilm);
    if (o.mesh_format != "vtp" && o.mesh_format != "ply") {
        throw UsageError("--mesh-format must be vtp or ply");
    }
    io::ReadOptions read;
    // Pixels: for an ILM source that segments them, and for the B-scans of the QC pictures.
    read.pixels = retina::ilm_needs_pixels(source) || !o.qc_dir.empty();
    read.iowa_bm = segmentation_bm(o.segmentation);
    io::HashedScan input = io::read_scan_hashed(file, read);
    io::Scan& scan = input.scan;
    const nlohmann::ordered_json segmentation =
        apply_segmentation_file(scan, o.segmentation, o.record_paths);
    const std::string& sha = input.sha256;
    prov.mark("read_hash");
    with_file_named(file, [&] { retina::require_onh_scan(scan); });
    std::optional<std::vector<retina::BmoPoint>> bmo;
    if (!o.bmo_file.empty()) {
        bmo = retina::is_radial_scan(scan)
                  ? with_file_named(file, [&] { return retina::read_radial_bmo_csv(o.bmo_file, scan); })
                  : retina::read_bmo_csv(o.bmo_file, scan.meta, scan.num_bscans());
    }
    // Lateral, then axial registration before any surface (docs/algorithms/onh.md): the
    // pixels and lines of every B-scan, and the user's BMO points with their B-scan.
    const retina::LateralRegistration lateral = with_file_named(
        file, [&] { return retina::register_laterally(scan, o.params.lateral_registration); });
    if (bmo && lateral.applied) retina::register_bmo_points_laterally(*bmo, scan, lateral);
    prov.mark("lateral_registration");
    const retina::AxialRegistration registration = with_file_named(
        file, [&] { return retina::register_axially(scan, o.params.axial_registration); });
    if (bmo && registration.applied) retina::register_bmo_points(*bmo, scan, registration);
    prov.mark("axial_registration");
    // The scan's record as read (pixels_loaded included), before the level set may free them.
    nlohmann::ordered_json preamble = eye_json_preamble("onh", file, sha, scan, o.record_paths);
    if (!segmentation.is_null()) preamble["input"]["segmentation"] = segmentation;
    // Without QC pictures nothing reads the pixels after the level set: it frees them, and
    // the eye's peak memory stays below twice the volume's (docs/algorithms/levelset.md).
    const retina::IlmSurface ilm = with_file_named(file, [&] {
        return o.qc_dir.empty() ? retina::build_ilm_surface_releasing_pixels(scan, source)
                                : retina::build_ilm_surface(scan, source);
    });
    prov.mark("ilm_surface");
    retina::OnhResult r =
        with_file_named(file, [&] { return retina::analyse_onh(scan, ilm, o.params, bmo); });
    r.axial_registration = registration;
    // The curvature's effect on this eye's MRW, from its own MRW segments (and its QC flag).
    retina::assess_curvature_mrw_effect(r.axial_registration, r.ellipse.points_mm,
                                        r.mrw_points_mm, o.params.axial_registration);
    r.lateral_registration = lateral;
    const retina::AxialRegistration& axial = r.axial_registration;
    r.qc_flags.insert(r.qc_flags.end(), lateral.qc_flags.begin(), lateral.qc_flags.end());
    r.notes.insert(r.notes.end(), lateral.notes.begin(), lateral.notes.end());
    r.qc_flags.insert(r.qc_flags.end(), axial.qc_flags.begin(), axial.qc_flags.end());
    r.notes.insert(r.notes.end(), axial.notes.begin(), axial.notes.end());
    prov.mark("analysis");
    const std::string who = log_name(file);
    for (const auto& f : r.qc_flags) spdlog::warn("{}: QC: {}", who, f);
    for (const auto& n : r.notes) spdlog::info("{}: {}", who, n);

    EyeResult out;
    auto& j = out.json;
    j = std::move(preamble);
    const nlohmann::ordered_json body =
        retina::onh_json(r, options_from_text(onh_options_text(o)));
    for (const auto& [k, v] : body.items()) j[k] = v;
    if (!o.bmo_file.empty()) {
        // The user's BMO file by its content; its path (which may name the patient) only on
        // request.
        // (Its SHA-256 is the option `bmo`, "sha256:HEX".)
        if (o.record_paths) j["options"]["bmo_file"] = o.bmo_file;
    }
    const auto cols = eyes_type_header(retina::ScanType::kOnh);
    const auto vals = retina::onh_csv_values(r);
    out.csv_header = eye_csv_header(o.record_paths);
    out.csv_row = eye_csv_values(file, sha, scan, o.record_paths);
    out.csv_header.insert(out.csv_header.end(), cols.begin(), cols.end());
    out.csv_row.insert(out.csv_row.end(), vals.begin(), vals.end());
    const std::string options_text = onh_options_text(o) + " subjects=" + subjects.fingerprint();
    attach_cohort_record(j, cols, vals, facts, options_text, retina::ScanType::kOnh, scan,
                         subjects, file);
    prov.add_input(sha, o.record_paths ? file : std::string());
    if (!segmentation.is_null()) {
        prov.add_input(segmentation["sha256"].get<std::string>(),
                       o.record_paths ? o.segmentation.file : std::string(),
                       {{"role", "segmentation"}});
    }
    prov.set_options(eye_provenance_options(options_text, o.qc_dir, o.record_paths));

    const std::string stem = o.qc_stem.empty() ? std::string("eye") : o.qc_stem;
    if (!o.qc_dir.empty()) {
        qc::write_onh_qc(scan, r, o.params, o.qc_dir, stem);
        prov.mark("qc_pictures");
    }
    if (!o.mesh_dir.empty()) {
        write_meshes(r, o, stem, mesh_provenance_line(prov));
        prov.mark("meshes");
    }
    j["provenance"] = prov.json();
    spdlog::info(
        "{}: {} eye, ILM {}, BMO area {:.4f} mm2, cup {:.4f} mm3, CONHT {:.4f} mm, "
        "MRW {:.4f} mm",
        who, r.eye, r.ilm_source, r.ellipse.area_mm2, r.cup_volume_mm3, r.conht_mm,
        r.mrw_mean_mm);
    return out;
}

}  // namespace octshape::app
