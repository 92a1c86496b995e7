#include "octshape/retina/cube_report.h"

#include "octshape/retina/etdrs.h"
#include "octshape/retina/record.h"

#include <cmath>
#include <sstream>

namespace octshape::retina {
namespace {

using J = nlohmann::ordered_json;

J num(double v) { return json_number(v); }

template <std::size_t N>
J arr(const std::array<double, N>& a) {
    J j = J::array();
    for (const double v : a) j.push_back(num(v));
    return j;
}

J points(const std::array<Eigen::Vector2d, 4>& c) {
    J j = J::array();
    for (const auto& p : c) j.push_back(J::array({p.x(), p.y()}));
    return j;
}

std::string csv_num(double v) { return csv_number(v); }

// How a CSV column stands in the JSON's "parameters" (the one list of parameter names: the CSV
// columns in order, and the JSON's keys from them).
enum class InJson {
    kScalar,     // the same key, the same value (null when missing)
    kVolume,     // the same, left out for line scans (3-D only)
    kDiskHead,   // the first column of a disk: the disk's JSON keys (disk_json), 3-D only
    kInDisk,     // written by its disk's head
};

struct Column {
    const char* name;
    double (*get)(const CubeResult&);
    InJson json = InJson::kScalar;
    const CubeDisk CubeResult::*disk = nullptr;  // kDiskHead: the disk
    const char* disk_prefix = nullptr;           // kDiskHead: its keys' prefix
    bool diameter = false;                       // kDiskHead: the column is the disk's diameter
    bool missing_in_line = false;                // a line scan has none (NA, null)
};

constexpr InJson kV = InJson::kVolume;
constexpr InJson kD = InJson::kInDisk;

// The stable CSV columns, in order (docs/outputs.md).
const std::vector<Column>& columns() {
    static const std::vector<Column> c{
        {"centre_x_mm", [](const CubeResult& r) { return r.centre_mm.x(); }},
        {"centre_y_mm", [](const CubeResult& r) { return r.centre_mm.y(); }, InJson::kScalar,
         nullptr, nullptr, false, true},
        {"cft_mm", [](const CubeResult& r) { return r.cft_mm; }},
        {"rim_height_mm", [](const CubeResult& r) { return r.rim_height_mm; }},
        {"pit_depth_mm", [](const CubeResult& r) { return r.pit_depth_mm; }},
        {"max_pit_slope_deg", [](const CubeResult& r) { return r.max_pit_slope_deg; }},
        {"pit_flat_diameter_mm", [](const CubeResult& r) { return r.pit_flat_diameter_mm; }},
        {"rim_diameter_mm", [](const CubeResult& r) { return r.rim.diameter_mm; },
         InJson::kDiskHead, &CubeResult::rim, "rim_disk", true},
        {"rim_disk_area_mm2", [](const CubeResult& r) { return r.rim.area_mm2; }, kD},
        {"rim_disk_major_eigenvalue_mm2",
         [](const CubeResult& r) { return r.rim.eigenvalues_mm2[0]; }, kD},
        {"rim_disk_minor_eigenvalue_mm2",
         [](const CubeResult& r) { return r.rim.eigenvalues_mm2[1]; }, kD},
        {"rim_disk_major_semi_axis_mm", [](const CubeResult& r) { return r.rim.semi_axes_mm[0]; },
         kD},
        {"rim_disk_minor_semi_axis_mm", [](const CubeResult& r) { return r.rim.semi_axes_mm[1]; },
         kD},
        {"slope_diameter_mm", [](const CubeResult& r) { return r.slope.diameter_mm; },
         InJson::kDiskHead, &CubeResult::slope, "slope_disk", true},
        {"slope_disk_area_mm2", [](const CubeResult& r) { return r.slope.area_mm2; }, kD},
        {"slope_disk_major_eigenvalue_mm2",
         [](const CubeResult& r) { return r.slope.eigenvalues_mm2[0]; }, kD},
        {"slope_disk_minor_eigenvalue_mm2",
         [](const CubeResult& r) { return r.slope.eigenvalues_mm2[1]; }, kD},
        {"slope_disk_major_semi_axis_mm",
         [](const CubeResult& r) { return r.slope.semi_axes_mm[0]; }, kD},
        {"slope_disk_minor_semi_axis_mm",
         [](const CubeResult& r) { return r.slope.semi_axes_mm[1]; }, kD},
        {"pit_flat_disk_area_mm2", [](const CubeResult& r) { return r.pit_flat.area_mm2; },
         InJson::kDiskHead, &CubeResult::pit_flat, "pit_flat_disk", false},
        {"pit_flat_disk_major_eigenvalue_mm2",
         [](const CubeResult& r) { return r.pit_flat.eigenvalues_mm2[0]; }, kD},
        {"pit_flat_disk_minor_eigenvalue_mm2",
         [](const CubeResult& r) { return r.pit_flat.eigenvalues_mm2[1]; }, kD},
        {"pit_flat_disk_major_semi_axis_mm",
         [](const CubeResult& r) { return r.pit_flat.semi_axes_mm[0]; }, kD},
        {"pit_flat_disk_minor_semi_axis_mm",
         [](const CubeResult& r) { return r.pit_flat.semi_axes_mm[1]; }, kD},
        {"rim_volume_mm3", [](const CubeResult& r) { return r.rim_volume_mm3; }, kV},
        {"inner_rim_volume_mm3", [](const CubeResult& r) { return r.inner_rim_volume_mm3; }, kV},
        {"pit_volume_mm3", [](const CubeResult& r) { return r.pit_volume_mm3; }, kV},
        {"alpha_mean_mm", [](const CubeResult& r) { return r.alpha_mean_mm; }},
        {"beta_mean_mm", [](const CubeResult& r) { return r.beta_mean_mm; }},
        {"rmse_um", [](const CubeResult& r) { return r.rmse_um; }},
    };
    return c;
}

void disk_json(J& v, const std::string& diameter, const std::string& prefix, const CubeDisk& d) {
    if (!diameter.empty()) v[diameter] = num(d.diameter_mm);
    v[prefix + "_area_mm2"] = num(d.area_mm2);
    v[prefix + "_eigenvalues_mm2"] = arr(d.eigenvalues_mm2);
    v[prefix + "_semi_axes_mm"] = arr(d.semi_axes_mm);
    v[prefix + "_normal"] = arr(d.normal);
}

// "parameters": the CSV's columns by their names, a disk's as disk_json writes it; a line scan
// has its 2-D ones only.
J parameters_json(const CubeResult& r) {
    J v;
    for (const Column& c : columns()) {
        switch (c.json) {
            case InJson::kScalar:
                v[c.name] = r.line_scan && c.missing_in_line ? J(nullptr) : num(c.get(r));
                break;
            case InJson::kVolume:
                if (!r.line_scan) v[c.name] = num(c.get(r));
                break;
            case InJson::kDiskHead:
                if (!r.line_scan) {
                    disk_json(v, c.diameter ? c.name : "", c.disk_prefix, r.*(c.disk));
                }
                break;
            case InJson::kInDisk:
                break;
        }
    }
    return v;
}

}  // namespace

J cube_json(const CubeResult& r, const CubeParams& p, const J& options) {
    J j;
    j["analysis"] = r.line_scan     ? "line scan (2-D, docs/algorithms/cube.md)"
                    : r.radial_scan ? "radial scan (3-D from the lines' half-lines)"
                                    : "volume (3-D)";
    j["orientation"] =
        "angles anatomical: 0 deg nasal, 90 deg superior, for both eyes; positions and disk "
        "points in grid mm (x along a B-scan = A-scan index * ScaleX, y across B-scans = "
        "B-scan index * Distance); heights are retinal thickness ILM - BM in mm; disk normals "
        "in the grid frame with z >= 0";
    j["options"] = options;
    J s;
    s["half_lines"] = r.line_scan     ? 2
                      : r.radial_scan ? static_cast<int>(r.half_lines.size())
                                      : p.num_half_lines;
    s["spacing_mm"] = r.sample_spacing_mm;
    j["sampling"] = s;
    J c;
    c["source"] = r.centre_source;
    c["search_centre_x_mm"] = r.search_centre_mm.x();
    c["search_centre_y_mm"] = r.search_centre_mm.y();
    c["tied_minima"] = r.num_tied_minima;
    j["centre"] = c;
    j["parameters"] = parameters_json(r);
    J noise;  // what sets the crest of RimPoint::kCrest (docs/algorithms/cube.md "Rim point")
    noise["thickness_noise_sd_um"] = num(r.thickness_noise_sd_um);
    noise["crest_tolerance_um"] =
        p.rim_point == RimPoint::kCrest ? num(3.0 * r.thickness_noise_sd_um) : J(nullptr);
    noise["radial_samples"] =
        r.noise_adaptive_samples ? "local fit (CFT pass), sector bins (final fit)" : "bilinear";
    noise["centre_fit_radius_mm"] = num(r.centre_fit_radius_mm);
    j["noise"] = noise;
    // What the lateral registration of the B-scans did before the map (docs/outputs.md).
    j["lateral_registration"] = lateral_registration_json(r.lateral_registration);
    J hl = J::array();
    for (const auto& h : r.half_lines) {
        J e;
        e["angle_deg"] = h.angle_deg;
        e["direction_grid"] = J::array({h.direction.x(), h.direction.y()});
        e["valid"] = h.valid;
        if (!h.valid) e["problem"] = h.problem;
        e["rim_radius_mm"] = num(h.rim_radius_mm);
        e["rim_height_mm"] = num(h.rim_height_mm);
        e["alpha_mm"] = num(h.alpha_mm);
        e["beta_mm"] = num(h.beta_mm);
        e["max_slope_deg"] = num(h.max_slope_deg);
        e["slope_point_mm"] = J::array({num(h.slope_point.x()), num(h.slope_point.y())});
        e["pit_flat_radius_mm"] = num(h.pit_flat_radius_mm);
        e["rmse_um"] = num(h.rmse_um);
        e["missing_samples"] = h.num_missing;
        if (h.valid) {
            e["interior_control_points_mm"] = points(h.interior.control);
            e["exterior_control_points_mm"] = points(h.exterior.control);
            e["fit_rounds"] = J::array({h.interior.rounds, h.exterior.rounds});
        }
        hl.push_back(std::move(e));
    }
    j["half_lines"] = std::move(hl);
    if (r.radial_scan) {
        // Positions above are in the radial frame: mm from the lines' crossing, x = SLO +x,
        // y = superior (docs/coordinates.md "Radial scans").
        const CubeRadial& q = r.radial;
        J rad;
        rad["frame"] = "mm from the lines' crossing: x = SLO +x, y = superior (up on the SLO)";
        rad["num_lines"] = q.num_lines;
        rad["line_length_mm"] = num(q.line_length_mm);
        rad["angular_step_deg"] = num(q.angular_step_deg);
        rad["regular_steps"] = q.regular;
        rad["max_line_miss_mm"] = num(q.max_miss_mm);
        rad["centre_offset_from_crossing_mm"] =
            J::array({num(q.centre_offset_mm.x()), num(q.centre_offset_mm.y())});
        rad["centre_offset_distance_mm"] = num(q.centre_offset_distance_mm);
        rad["centre_offset_limit_mm"] = num(q.centre_offset_limit_mm);
        rad["bmo_fields"] = J{{"bscans_with_fields", q.num_bmo_fields}, {"used", false}};
        j["radial"] = std::move(rad);
        J feet = J::array();
        for (const auto& h : r.half_lines) {
            feet.push_back(J::array({num(h.foot_mm.x()), num(h.foot_mm.y())}));
        }
        j["radial"]["half_line_feet_mm"] = std::move(feet);
    }
    j["qc_flags"] = r.qc_flags;
    j["notes"] = r.notes;
    return j;
}

std::vector<std::string> cube_csv_header() {
    std::vector<std::string> h{record::name(record::Name::kAnalysis), "centre_source"};
    for (const auto& c : columns()) h.emplace_back(c.name);
    h.emplace_back("qc_flags");
    // Appended after qc_flags (columns are only ever appended): the map's node noise, the
    // covariate the per-eye precision and bias depend on (docs/outputs.md, "How precise").
    h.emplace_back("thickness_noise_sd_um");
    return h;
}

std::vector<std::string> macula_csv_header() {
    std::vector<std::string> h = cube_csv_header();
    for (auto& c : etdrs_csv_header()) h.push_back(std::move(c));
    return h;
}

const std::vector<std::string>& macula_key_columns() {
    static const std::vector<std::string> k{"cft_mm",          "rim_height_mm",
                                            "pit_depth_mm",    "max_pit_slope_deg",
                                            "rim_diameter_mm", "pit_volume_mm3",
                                            "rmse_um"};
    return k;
}

std::vector<std::string> cube_csv_values(const CubeResult& r) {
    std::vector<std::string> v{r.line_scan ? "line" : r.radial_scan ? "radial" : "volume",
                               r.centre_source};
    for (const auto& c : columns()) {
        const double x = c.get(r);
        // A line scan has no y across B-scans: NA, as in the JSON.
        v.push_back(r.line_scan && c.missing_in_line ? "NA" : csv_num(x));
    }
    std::string flags;
    for (const auto& f : r.qc_flags) flags += (flags.empty() ? "" : ";") + f;
    v.push_back(flags);
    v.push_back(csv_num(r.thickness_noise_sd_um));
    return v;
}

}  // namespace octshape::retina
