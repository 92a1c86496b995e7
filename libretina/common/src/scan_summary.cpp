#include "octshape/retina/scan_summary.h"

#include <cmath>
#include <numbers>

#include "octshape/retina/radial_geometry.h"
#include "octshape/retina/scan_geometry.h"

namespace octshape::retina {
namespace {

using nlohmann::json;

// Rounds for display in JSON without losing what the file holds (12 significant digits).
double tidy(double v) {
    if (!std::isfinite(v) || v == 0.0) return v;
    const double mag = std::pow(10.0, 11 - static_cast<int>(std::floor(std::log10(std::fabs(v)))));
    return std::round(v * mag) / mag;
}

json grid_json(const io::ThicknessGrid& g, const ScanGeometry& geo, bool volume_like) {
    json j;
    j["type"] = g.type;
    j["kind"] = g.is_circular() ? "circular" : g.is_rectangular() ? "rectangular" : "unknown";
    j["from_header"] = g.from_header;
    j["centre_slo_mm"] = {tidy(g.centre_x_slo_mm), tidy(g.centre_y_slo_mm)};
    if (volume_like) {
        const Eigen::Vector2d c = geo.slo_to_grid({g.centre_x_slo_mm, g.centre_y_slo_mm});
        j["centre_grid_mm"] = {tidy(c.x()), tidy(c.y())};
    } else {
        j["centre_grid_mm"] = nullptr;
    }
    if (g.is_circular()) {
        j["diameters_mm"] = {g.diameters_mm[0], g.diameters_mm[1], g.diameters_mm[2]};
        j["central_thickness_mm"] = tidy(g.central_thickness_mm);
    } else if (g.is_rectangular()) {
        j["rows"] = g.rows;
        j["cols"] = g.cols;
    }
    return j;
}

// A radial scan as it is: lines, their length, crossing, misses and angular steps.
json radial_json(const io::Scan& scan) {
    json j;
    try {
        const RadialGeometry g = radial_geometry(scan);
        j["num_lines"] = static_cast<int>(g.lines.size());
        j["line_length_mm"] = tidy(g.mean_length_mm);
        j["line_length_from_header_mm"] = tidy(g.header_length_mm);
        j["crossing_slo_mm"] = {tidy(g.crossing_slo_mm.x()), tidy(g.crossing_slo_mm.y())};
        j["max_miss_mm"] = tidy(g.max_miss_mm);
        j["rms_miss_mm"] = tidy(g.rms_miss_mm);
        j["lines_cross"] = g.lines_cross;
        j["angular_step_deg"] = tidy(g.nominal_step_deg);
        j["min_step_deg"] = tidy(g.min_step_deg);
        j["max_step_deg"] = tidy(g.max_step_deg);
        j["step_tolerance_relative"] = RadialGeometry::kStepTolerance;
        j["regular"] = g.regular;
        j["irregular_steps"] = g.irregular_steps;
        j["angle_convention"] = "anatomical: 0 deg = nasal, 90 deg = superior, both eyes";
        json lines = json::array();
        for (const RadialLine& l : g.lines) {
            lines.push_back({{"bscan", l.bscan},
                             {"angle_deg", tidy(l.angle_deg)},
                             {"line_angle_deg", tidy(l.line_angle_deg)},
                             {"length_mm", tidy(l.length_mm)},
                             {"miss_mm", tidy(l.miss_mm)}});
        }
        j["lines"] = lines;
        j["bmo_fields"] = {{"bscans_with_fields", g.num_bmo_fields},
                           {"used", false},
                           {"why", g.num_bmo_fields > 0
                                       ? "HSF-OCT-104 BmoCoordLeft/Right read; their meaning is "
                                         "unverified, so no analysis uses them"
                                       : "not in this file (HSF-OCT-104 only)"}};
    } catch (const std::exception& e) {
        j["error"] = e.what();
    }
    return j;
}

}  // namespace

json scan_summary(const io::Scan& scan, const SummaryOptions& options) {
    const io::ScanMeta& m = scan.meta;
    const ScanGeometry geo(scan);
    const bool circle = m.pattern == io::ScanPattern::kCircle;
    const bool volume_like = m.pattern == io::ScanPattern::kVolume ||
                             m.pattern == io::ScanPattern::kFastVolume ||
                             m.pattern == io::ScanPattern::kLine;
    json j;
    j["file"] = scan.source_path;
    j["format"] = io::to_string(m.format);
    j["format_version"] = m.version;
    j["eye"] = io::to_string(m.laterality);
    j["scan_pattern"] = io::to_string(m.pattern);
    j["scan_pattern_code"] = m.scan_pattern_code;
    j["num_bscans"] = scan.num_bscans();
    j["ascans_per_bscan"] = m.size_x;
    j["pixels_per_ascan"] = m.size_z;
    j["scale_x_mm"] = tidy(m.scale_x_mm);
    j["scale_z_mm"] = tidy(m.scale_z_mm);
    j["distance_mm"] = tidy(m.distance_mm);
    j["scan_depth_mm"] = tidy(m.size_z * m.scale_z_mm);
    if (circle) {
        // Circle scans: ScaleX is circumference / SizeX; End holds the centre on the SLO.
        j["circle_circumference_mm"] = tidy(m.size_x * m.scale_x_mm);
        j["circle_radius_mm"] = tidy(m.size_x * m.scale_x_mm / (2.0 * std::numbers::pi));
        if (!scan.bscans.empty()) {
            const io::BScan& b = scan.bscans.front();
            j["circle_centre_slo_mm"] = {tidy(b.end_x_mm), tidy(b.end_y_mm)};
            j["circle_radius_from_positions_mm"] =
                tidy(std::hypot(b.start_x_mm - b.end_x_mm, b.start_y_mm - b.end_y_mm));
        }
    } else if (is_radial_scan(scan)) {
        // The B-scans are lines through one point: no parallel spacing, no volume extent.
        j["bscan_width_mm"] = tidy((m.size_x - 1) * m.scale_x_mm);
        j["radial"] = radial_json(scan);
    } else {
        j["bscan_width_mm"] = tidy((m.size_x - 1) * m.scale_x_mm);
        j["volume_height_mm"] = tidy(std::max(0, scan.num_bscans() - 1) * m.distance_mm);
    }

    const SpacingReport& s = geo.spacing();
    json spacing;
    spacing["header_mm"] = tidy(s.header_distance_mm);
    spacing["positions_known"] = s.positions_known;
    if (s.positions_known) {
        spacing["measured_mean_mm"] = tidy(s.mean_mm);
        spacing["measured_min_mm"] = tidy(s.min_mm);
        spacing["measured_max_mm"] = tidy(s.max_mm);
        spacing["max_relative_deviation"] = tidy(s.max_relative_deviation);
        spacing["uniform"] = s.uniform;
        spacing["matches_header"] = s.matches_header;
    }
    spacing["tolerance_relative"] = SpacingReport::kUniformTolerance;
    if (!j.contains("radial")) j["bscan_spacing"] = spacing;

    if (volume_like) {
        json o;
        o["convention"] = "anatomical: 0 deg = nasal, 90 deg = superior, both eyes";
        o["grid_x_points"] = geo.x_is_nasal() ? "nasal" : "temporal";
        if (m.pattern != io::ScanPattern::kLine) {
            o["grid_y_points"] = geo.y_is_superior() ? "superior" : "inferior";
        }
        o["from_bscan_positions"] = geo.oriented_from_positions();
        j["orientation"] = o;
    }

    j["slo"] = {{"width_px", m.size_x_slo},
                {"height_px", m.size_y_slo},
                {"scale_x_mm", tidy(m.scale_x_slo_mm)},
                {"scale_y_mm", tidy(m.scale_y_slo_mm)},
                {"field_size_deg", m.field_size_slo_deg}};

    json layers = json::array();
    for (int k = 0; k < scan.num_lines(); ++k) {
        layers.push_back({{"index", k},
                          {"name", scan.line_name(k)},
                          {"valid_percent", tidy(100.0 * scan.valid_fraction(k))}});
    }
    j["layers"] = layers;

    json grids = json::array();
    for (const io::ThicknessGrid& g : scan.grids) grids.push_back(grid_json(g, geo, volume_like));
    j["thickness_grids"] = grids;
    j["pixels_loaded"] = scan.pixels_loaded;
    j["notes"] = scan.notes;

    if (options.identifiers) {
        const io::Identifiers& id = m.ids;
        json p;
        p["id"] = id.id;
        p["reference_id"] = id.reference_id;
        p["pid"] = id.pid;
        p["patient_id"] = id.patient_id;
        p["date_of_birth"] = id.dob_ole ? json(io::ole_date_to_iso_date(*id.dob_ole)) : json();
        p["vid"] = id.vid;
        p["visit_id"] = id.visit_id;
        p["exam_time_utc"] =
            m.exam_time_filetime ? json(io::filetime_to_iso(*m.exam_time_filetime)) : json();
        p["visit_date"] =
            m.visit_date_ole ? json(io::ole_date_to_iso_date(*m.visit_date_ole)) : json();
        j["identifiers"] = p;
    }
    return j;
}

}  // namespace octshape::retina
