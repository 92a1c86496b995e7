#include "octshape/retina/onh_report.h"

#include <cmath>
#include <cstdio>

#include "octshape/retina/report_util.h"
#include "octshape/retina/record.h"

namespace octshape::retina {
namespace {

using J = nlohmann::ordered_json;

std::string sector_name(std::size_t k) {
    char b[32];
    std::snprintf(b, sizeof b, "mrw_sector_%03d_mm", static_cast<int>(30 * k));
    return b;
}

std::string inplane_sector_name(std::size_t k) {
    char b[40];
    std::snprintf(b, sizeof b, "mrw_inplane_sector_%03d_mm", static_cast<int>(30 * k));
    return b;
}

struct Column {
    const char* name;
    double (*get)(const OnhResult&);
};

// The stable numeric CSV columns, in order (docs/outputs.md); the sectors follow them.
const std::vector<Column>& columns() {
    static const std::vector<Column> c{
        {"cup_volume_mm3", [](const OnhResult& r) { return r.cup_volume_mm3; }},
        {"conht_mm", [](const OnhResult& r) { return r.conht_mm; }},
        {"bmo_volume_mm3", [](const OnhResult& r) { return r.bmo_volume_mm3; }},
        {"total_volume_mm3", [](const OnhResult& r) { return r.total_volume_mm3; }},
        {"annular_volume_mm3", [](const OnhResult& r) { return r.annular_volume_mm3; }},
        {"bending_energy", [](const OnhResult& r) { return r.bending_energy; }},
        {"bmo_area_mm2", [](const OnhResult& r) { return r.ellipse.area_mm2; }},
        {"bmo_semi_major_mm", [](const OnhResult& r) { return r.ellipse.semi_major_mm; }},
        {"bmo_semi_minor_mm", [](const OnhResult& r) { return r.ellipse.semi_minor_mm; }},
        {"bmo_orientation_deg", [](const OnhResult& r) { return r.ellipse.orientation_deg; }},
        {"bmo_orientation_anatomical_deg",
         [](const OnhResult& r) { return r.bmo_orientation_anatomical_deg; }},
        {"bmo_centre_x_mm", [](const OnhResult& r) { return r.ellipse.centre_mm.x(); }},
        {"bmo_centre_y_mm", [](const OnhResult& r) { return r.ellipse.centre_mm.y(); }},
        {"mrw_mean_mm", [](const OnhResult& r) { return r.mrw_mean_mm; }},
        {"mrw_min_mm", [](const OnhResult& r) { return r.mrw_min_mm; }},
        {"mrw_max_mm", [](const OnhResult& r) { return r.mrw_max_mm; }},
        {"mrw_area_mm2", [](const OnhResult& r) { return r.mrw_area_mm2; }},
        {"bmo_points_measured",
         [](const OnhResult& r) { return static_cast<double>(r.bmo_measured.size()); }},
        {"bmo_ellipse_rms_um", [](const OnhResult& r) { return 1e3 * r.ellipse.rms_residual_mm; }},
        {"rpe_fill_area_mm2", [](const OnhResult& r) { return r.rpe_fill_area_mm2; }},
        {"ilm_filled_vertices",
         [](const OnhResult& r) { return static_cast<double>(r.ilm_filled_vertices); }},
    };
    return c;
}

J vec3(const Eigen::Vector3d& v) { return J::array({v.x(), v.y(), v.z()}); }

// The `radial` object of a radial scan's JSON (docs/outputs.md).
J radial_json(const OnhResult& r) {
    J rad;
    rad["lines"] = r.radial_lines;
    rad["crossing_mm"] = J::array({r.radial_crossing_mm.x(), r.radial_crossing_mm.y()});
    rad["scanned_radius_mm"] = r.radial_scanned_radius_mm;
    rad["grid_step_mm"] = r.radial_grid_step_mm;
    rad["max_line_miss_mm"] = r.radial_max_miss_mm;
    rad["max_step_deg"] = r.radial_max_step_deg;
    rad["interpolation"] =
        "between the lines linear in angle at constant distance from the crossing";
    rad["mrw_inplane_mean_mm"] = json_number(r.mrw_inplane_mean_mm);
    rad["mrw_inplane_min_mm"] = json_number(r.mrw_inplane_min_mm);
    rad["mrw_inplane_max_mm"] = json_number(r.mrw_inplane_max_mm);
    if (r.ilm_source == "levelset") {
        rad["levelset_leak_bscans"] = r.levelset_leak_bscans;
        rad["levelset_leak_fallback_ascans"] = r.levelset_leak_fallback_ascans;
        rad["levelset_leak_cut_ascans"] = r.levelset_leak_cut_ascans;
    }
    J isec = J::object();
    J ipts_n = J::object();
    for (std::size_t k = 0; k < 12; ++k) {
        isec[std::to_string(30 * k)] = json_number(r.mrw_inplane_sector_mm[k]);
        ipts_n[std::to_string(30 * k)] = r.mrw_inplane_sector_points[k];
    }
    rad["mrw_inplane_sector_mm"] = isec;
    rad["mrw_inplane_sector_points"] = ipts_n;
    J ip = J::array();
    for (const InplaneMrw& m : r.mrw_inplane) {
        J e;
        e["bscan"] = m.bscan;
        e["side"] = m.side;
        e["anatomical_deg"] = m.anatomical_deg;
        e["point_mm"] = vec3(m.bmo_mm);
        e["mrw_point_mm"] = vec3(m.ilm_mm);
        e["mrw_mm"] = m.mrw_mm;
        ip.push_back(std::move(e));
    }
    rad["mrw_inplane_points"] = std::move(ip);
    return rad;
}

}  // namespace

J onh_json(const OnhResult& r, const J& options) {
    J j;
    j["analysis"] = "optic nerve head (3-D, thesis 8.1)";
    j["orientation"] =
        "angles anatomical: 0 deg nasal, 90 deg superior, for both eyes (OS mirrored); "
        "positions in grid mm (x along a B-scan = A-scan index * ScaleX, y across B-scans = "
        "B-scan index * Distance, z = height = -depth * ScaleZ); h = ILM height above the RPE";
    j["options"] = options;
    j["sources"] = J{{"ilm_source", r.ilm_source}, {"bmo_source", r.bmo_source}};
    {
        // Per B-scan (index = B-scan, from 0): the axial motion estimated (+ = the B-scan lay
        // deeper than the eye) and removed when applied.
        const AxialRegistration& a = r.axial_registration;
        J reg;
        reg["applied"] = a.applied;
        reg["model"] =
            "BM depth = per-B-scan offset + smooth polynomial surface (robust least squares); "
            "the offsets a polynomial of the same degree across B-scans explains belong to the "
            "eye (volumes; its curvature across B-scans taken equal to the BM's along them), "
            "the rest is motion (docs/algorithms/onh.md)";
        reg["rms_shift_um"] = a.rms_shift_um;
        reg["max_abs_shift_um"] = a.max_abs_shift_um;
        reg["residual_rms_um"] = a.residual_rms_um;
        reg["curvature_to_motion_um"] = a.curvature_to_motion_um;
        reg["curvature_mrw_effect_um"] = a.curvature_mrw_effect_um;
        reg["bm_values_used"] = a.bm_values_used;
        reg["bm_values_rejected"] = a.bm_values_rejected;
        reg["bscans_not_estimated"] = a.bscans_not_estimated;
        put_shifts(reg, a.shift_um, a.estimated);
        j["axial_registration"] = std::move(reg);
    }
    j["lateral_registration"] = lateral_registration_json(r.lateral_registration);

    J v;
    v["has_cup"] = r.has_cup;
    for (const auto& c : columns()) {
        if (std::string(c.name) == "bmo_points_measured") break;
        v[c.name] = json_number(c.get(r));
    }
    J sectors = J::object();
    for (std::size_t k = 0; k < 12; ++k) {
        sectors[std::to_string(30 * k)] = json_number(r.mrw_sector_mm[k]);
    }
    v["mrw_sector_mm"] = sectors;
    J sector_points = J::object();
    for (std::size_t k = 0; k < 12; ++k) {
        sector_points[std::to_string(30 * k)] = r.mrw_sector_points[k];
    }
    v["mrw_sector_points"] = sector_points;
    v["ilm_centre_height_mm"] = json_number(r.ilm_centre_height_mm);
    v["rpe_centre_height_mm"] = json_number(r.rpe_centre_height_mm);
    v["bmo_region_area_mm2"] = r.bmo_region_area_mm2;
    v["bmo_tensor_eigenvalues"] =
        J::array({json_number(r.bmo_tensor_eigenvalues[0]), json_number(r.bmo_tensor_eigenvalues[1]),
                  json_number(r.bmo_tensor_eigenvalues[2])});
    // Radial scans (null for volumes): the BMO-MRW in the B-scan planes.
    v["mrw_inplane_mean_mm"] = json_number(r.mrw_inplane_mean_mm);
    J inplane = J::object();
    for (std::size_t k = 0; k < 12; ++k) {
        inplane[std::to_string(30 * k)] = json_number(r.mrw_inplane_sector_mm[k]);
    }
    v["mrw_inplane_sector_mm"] = inplane;
    j["parameters"] = v;

    J b;
    b["source"] = r.bmo_source;
    b["measured_points"] = r.bmo_measured.size();
    b["ellipse_rms_residual_um"] = 1e3 * r.ellipse.rms_residual_mm;
    if (r.bmo_source == "automatic") {
        b["gap_area_mm2"] = r.bmo_gap_area_mm2;
        b["other_gaps"] = r.bmo_other_gaps;
        b["points_per_bscan"] = r.bmo_points_per_bscan;
    }
    J measured = J::array();
    for (const auto& m : r.bmo_measured) {
        J e;
        e["x_mm"] = m.mm.x();
        e["y_mm"] = m.mm.y();
        e["z_mm"] = m.mm.z();
        e["bscan"] = m.bscan;
        e["side"] = m.side;
        measured.push_back(std::move(e));
    }
    b["measured"] = std::move(measured);
    j["bmo"] = std::move(b);

    J pts = J::array();
    for (std::size_t i = 0; i < r.ellipse.points_mm.size(); ++i) {
        J e;
        e["parameter_deg"] = r.ellipse.parameter_rad[i] * 180.0 / 3.141592653589793;
        e["anatomical_deg"] = r.bmo_anatomical_deg[i];
        e["point_mm"] = vec3(r.ellipse.points_mm[i]);
        e["mrw_point_mm"] = vec3(r.mrw_points_mm[i]);
        e["mrw_mm"] = r.mrw_mm[i];
        pts.push_back(std::move(e));
    }
    j["bmo_points"] = std::move(pts);

    if (r.radial) j["radial"] = radial_json(r);

    J q;
    q["rpe_filled_vertices"] = r.rpe_filled_vertices;
    q["rpe_fill_area_mm2"] = r.rpe_fill_area_mm2;
    q["rpe_fill_outside_bmo_mm2"] = r.rpe_fill_outside_bmo_mm2;
    q["rpe_fill_relative_residual"] = r.rpe_fill_residual;
    q["ilm_filled_vertices"] = r.ilm_filled_vertices;
    q["ilm_filled_in_disc"] = r.ilm_filled_in_disc;
    q["ilm_faces_outside_rpe"] = r.faces_outside_rpe;
    J s;
    s["vertices"] = r.ilm_quality.vertices;
    s["faces"] = r.ilm_quality.faces;
    s["boundary_edges"] = r.ilm_quality.boundary_edges;
    s["nonmanifold_edges"] = r.ilm_quality.nonmanifold_edges;
    s["degenerate_faces"] = r.ilm_quality.degenerate_faces;
    s["negative_projected_area_mm2"] = r.ilm_quality.negative_projected_area_mm2;
    s["quality"] = json_number(r.ilm_quality.quality);
    s["faces_reversed"] = r.ilm_flipped;
    q["ilm_surface"] = s;
    q["oriented_from_bscan_positions"] = r.oriented_from_positions;
    q["analysis_seconds"] = r.seconds;
    j["qc"] = q;
    j["qc_flags"] = r.qc_flags;
    j["notes"] = r.notes;
    return j;
}

std::vector<std::string> onh_csv_header() {
    std::vector<std::string> h{"ilm_source", "bmo_source"};
    for (const auto& c : columns()) h.emplace_back(c.name);
    for (std::size_t k = 0; k < 12; ++k) h.push_back(sector_name(k));
    h.emplace_back("qc_flags");
    // Appended (radial scans; NA for volumes): the in-plane MRW.
    h.emplace_back("mrw_inplane_mean_mm");
    for (std::size_t k = 0; k < 12; ++k) h.push_back(inplane_sector_name(k));
    // Appended: which analysis read the scan (volume | radial), as the macula's first column;
    // a table's rows of two analyses are never pooled (octshape stats keeps one).
    h.push_back(record::name(record::Name::kAnalysis));
    return h;
}

const std::vector<std::string>& onh_key_columns() {
    static const std::vector<std::string> k{"cup_volume_mm3", "conht_mm",    "bmo_volume_mm3",
                                            "bmo_area_mm2",   "mrw_mean_mm", "bending_energy"};
    return k;
}

std::vector<std::string> onh_csv_values(const OnhResult& r) {
    std::vector<std::string> v{r.ilm_source, r.bmo_source};
    for (const auto& c : columns()) v.push_back(csv_number(c.get(r)));
    for (std::size_t k = 0; k < 12; ++k) v.push_back(csv_number(r.mrw_sector_mm[k]));
    std::string flags;
    for (const auto& f : r.qc_flags) flags += (flags.empty() ? "" : ";") + f;
    v.push_back(flags);
    v.push_back(csv_number(r.mrw_inplane_mean_mm));
    for (std::size_t k = 0; k < 12; ++k) v.push_back(csv_number(r.mrw_inplane_sector_mm[k]));
    v.emplace_back(r.radial ? "radial" : "volume");
    return v;
}

}  // namespace octshape::retina
