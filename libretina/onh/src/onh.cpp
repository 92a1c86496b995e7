#include "octshape/retina/onh.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numbers>
#include <sstream>
#include <stdexcept>
#include <tuple>

#include "octshape/error.h"
#include "octshape/mesh/closest_point.h"
#include "octshape/mesh/envt.h"
#include "octshape/mesh/metrics.h"
#include "octshape/retina/levelset.h"
#include "levelset_stages.h"
#include "onh_stages.h"
#include "octshape/retina/radial_geometry.h"
#include "octshape/retina/scan_geometry.h"

namespace octshape::retina {
namespace {

constexpr double kPi = std::numbers::pi;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

std::string fmt_mm(double v, int digits = 4) {
    char b[64];
    std::snprintf(b, sizeof b, "%.*f", digits, v);
    return b;
}

MeshQuality mesh_quality_report(const mesh::Vertices& V,
                                const mesh::Faces& F,
                                const mesh::FaceGeometry& g,
                                const Eigen::VectorXd& projected) {
    MeshQuality q;
    q.vertices = static_cast<int>(V.rows());
    q.faces = static_cast<int>(F.rows());
    const mesh::Adjacency adj = mesh::build_adjacency(F, static_cast<int>(V.rows()));
    q.boundary_edges = adj.boundary_edges;
    q.nonmanifold_edges = adj.nonmanifold_edges;
    for (Eigen::Index f = 0; f < F.rows(); ++f) {
        if (!(g.areas(f) > 0.0)) ++q.degenerate_faces;
        if (projected(f) < 0.0) q.negative_projected_area_mm2 -= projected(f);
    }
    q.quality = mesh::mesh_quality(V, F);
    return q;
}

}  // namespace

std::string to_string(IlmSource source) {
    switch (source) {
        case IlmSource::kLevelSet:
            return "levelset";
        case IlmSource::kDevice:
            return "device";
    }
    return "device";
}

IlmSource ilm_source_from_string(const std::string& name) {
    if (name == "levelset") return IlmSource::kLevelSet;
    if (name == "device") return IlmSource::kDevice;
    throw UsageError("--ilm: unknown ILM source '" + name + "' (valid: levelset, device)");
}

namespace {

IlmSurface surface_from_levelset(const LevelSetResult& ls) {
    IlmSurface out;
    out.V = ls.V;
    out.F = ls.F;
    out.source = "levelset";
    for (const std::string& w : ls.warnings) {
        (w.rfind(levelset_detail::kLeakFlag, 0) == 0 ? out.qc_flags : out.notes).push_back(w);
    }
    std::ostringstream s;
    s << "level-set ILM: " << ls.iterations << " iterations ("
      << (ls.converged ? "converged" : "stopped at the iteration limit") << "), "
      << ls.raw_faces << " marching-cubes faces, " << ls.F.rows() << " faces after clip and "
      << "component, " << ls.rofi_iterations << " RoFi iterations";
    out.notes.push_back(s.str());
    if (!ls.converged) out.qc_flags.push_back("level set did not converge");
    if (ls.front_reached_window_edge) {
        out.qc_flags.push_back("level-set front reached the edge of its depth window");
    }
    if (ls.missing_ilm_columns > 0) {
        out.notes.push_back(std::to_string(ls.missing_ilm_columns) +
                            " columns without a device ILM value were filled for the "
                            "level set's start");
    }
    return out;
}

}  // namespace

IlmSurface levelset_ilm_surface(const io::Scan& scan) {
    if (is_radial_scan(scan)) return onh_detail::radial_levelset_ilm_surface(scan);
    require_onh_volume(scan);
    return surface_from_levelset(levelset_ilm(scan));
}

IlmSurface device_ilm_surface(const io::Scan& scan) {
    if (is_radial_scan(scan)) return onh_detail::radial_device_ilm_surface(scan);
    require_onh_volume(scan);
    GridSurface s = line_height_field(scan, io::Layer::kILM);
    IlmSurface out;
    out.source = "device";
    const int missing = static_cast<int>(
        std::count_if(s.z.begin(), s.z.end(), [](double v) { return std::isnan(v); }));
    if (missing == static_cast<int>(s.z.size())) {
        throw AnalysisError("the ILM segmentation is missing everywhere");
    }
    if (missing > 0) {
        thin_plate_fill(s);
        out.notes.push_back(std::to_string(missing) +
                            " missing device ILM values were thin-plate filled");
    }
    out.filled_vertices = missing;
    out.vertex_filled = s.filled;
    graph_mesh(s, out.V, out.F);
    return out;
}

IlmSurface build_ilm_surface(const io::Scan& scan, IlmSource source) {
    switch (source) {
        case IlmSource::kLevelSet:
            return levelset_ilm_surface(scan);
        case IlmSource::kDevice:
            return device_ilm_surface(scan);
    }
    throw UsageError("unknown ILM source");
}

IlmSurface build_ilm_surface_releasing_pixels(io::Scan& scan, IlmSource source) {
    if (source != IlmSource::kLevelSet) return build_ilm_surface(scan, source);
    if (is_radial_scan(scan)) {
        // The radial pixels (24 B-scans) are small beside the surface's stages: freed after.
        IlmSurface s = onh_detail::radial_levelset_ilm_surface(scan);
        for (auto& bs : scan.bscans) bs.pixels = std::vector<float>();
        scan.pixels_loaded = false;
        return s;
    }
    require_onh_volume(scan);
    return surface_from_levelset(levelset_ilm_releasing_pixels(scan));
}

bool ilm_needs_pixels(IlmSource source) {
    switch (source) {
        case IlmSource::kLevelSet:
            return true;
        case IlmSource::kDevice:
            return false;
    }
    return true;
}

OnhEnfaceGrid onh_enface_heights(const OnhResult& r) {
    const GridSurface& g = r.rpe;
    OnhEnfaceGrid out;
    out.cols = std::max(0, g.cols - 1);
    out.rows = std::max(0, g.rows - 1);
    out.dx_mm = g.dx_mm;
    out.dy_mm = g.dy_mm;
    out.height_mm.assign(static_cast<std::size_t>(out.cols) * static_cast<std::size_t>(out.rows),
                         std::numeric_limits<double>::quiet_NaN());
    if (out.height_mm.empty()) return out;
    std::vector<double> top(out.height_mm.size(), -std::numeric_limits<double>::infinity());
    const mesh::FaceGeometry fg = mesh::face_geometry(r.ilm_V, r.ilm_F);
    for (Eigen::Index f = 0; f < r.ilm_F.rows(); ++f) {
        if (std::isnan(r.face_height_mm(f))) continue;
        const int a = std::clamp(static_cast<int>(fg.centroids(f, 0) / g.dx_mm), 0, out.cols - 1);
        const int b = std::clamp(static_cast<int>(fg.centroids(f, 1) / g.dy_mm), 0, out.rows - 1);
        const auto i = static_cast<std::size_t>(b) * static_cast<std::size_t>(out.cols) +
                       static_cast<std::size_t>(a);
        if (fg.centroids(f, 2) > top[i]) {
            top[i] = fg.centroids(f, 2);
            out.height_mm[i] = r.face_height_mm(f);
        }
    }
    return out;
}

void OnhParams::validate() const {
    if (bmo_points < 8 || bmo_points > 100000) {
        throw UsageError("bmo_points must be in [8, 100000]");
    }
    if (!(disc_radius_mm > 0.0) || !std::isfinite(disc_radius_mm)) {
        throw UsageError("disc_radius_mm must be a positive number");
    }
    detection.validate();
    lateral_registration.validate();
}

void require_onh_scan(const io::Scan& scan) {
    if (is_radial_scan(scan)) {
        (void)onh_detail::radial_onh_grid(scan);
    } else {
        require_onh_volume(scan);
    }
}

void require_onh_volume(const io::Scan& scan) {
    const auto pat = scan.meta.pattern;
    const bool volume = pat == io::ScanPattern::kVolume || pat == io::ScanPattern::kFastVolume ||
                        (pat == io::ScanPattern::kUnknown && scan.num_bscans() > 1);
    if (!volume) {
        throw AnalysisError("scan pattern '" + std::string(io::to_string(pat)) +
                            "' cannot be analysed as an optic nerve head: a volume or radial scan is "
                            "needed");
    }
    if (scan.num_bscans() < 3 || scan.meta.size_x < 3) {
        throw AnalysisError("the volume has fewer than 3 B-scans or 3 A-scans");
    }
    if (!(scan.meta.distance_mm > 0.0)) {
        throw AnalysisError("volume scan without a B-scan distance in its header");
    }
    if (!(scan.meta.scale_x_mm > 0.0) || !(scan.meta.scale_z_mm > 0.0)) {
        throw AnalysisError("the scan's ScaleX/ScaleZ are not positive");
    }
}

OnhRegions measure_onh_regions(const mesh::Vertices& V,
                               const mesh::Faces& F,
                               const GridSurface& rpe,
                               const BmoEllipse& ellipse,
                               double disc_radius_mm) {
    OnhRegions m;
    const Eigen::Index nf = F.rows();
    m.face_height_mm.resize(nf);
    m.face_region.assign(static_cast<std::size_t>(nf), 0);
    const Eigen::Vector2d c = ellipse.centre_mm;
    for (Eigen::Index f = 0; f < nf; ++f) {
        const Eigen::Vector3d a = V.row(F(f, 0));
        const Eigen::Vector3d b = V.row(F(f, 1));
        const Eigen::Vector3d d = V.row(F(f, 2));
        const Eigen::Vector3d centroid = (a + b + d) / 3.0;
        // Eq. 8.9: A_i = 1/2 (e0 x e1)_z of the projected triangle, signed.
        const double area =
            0.5 * ((b.x() - a.x()) * (d.y() - a.y()) - (d.x() - a.x()) * (b.y() - a.y()));
        // Correspondence: the RPE height under the centroid, bilinear on the RPE grid (finer
        // than the nearest node of Eq. 8.3-8.4).
        const double under = rpe.bilinear(centroid.x(), centroid.y());
        std::uint8_t reg = 0;
        if (std::isnan(under)) {
            reg = kRegionOutside;
            ++m.faces_outside_rpe;
            m.face_height_mm(f) = std::numeric_limits<double>::quiet_NaN();
        } else {
            const double h = centroid.z() - under;  // Eq. 8.9
            m.face_height_mm(f) = h;
            if (ellipse.inside(centroid.x(), centroid.y())) reg |= kRegionBmo;
            if ((centroid.head<2>() - c).norm() <= disc_radius_mm) reg |= kRegionDisc;
            if (h < 0.0) reg |= kRegionCup;
            const double ah = area * h;  // A_i h_i with A_i signed
            if (reg & kRegionCup) {
                m.cup_volume_mm3 -= ah;  // Eq. 8.7-8.8, reported positive
            } else {
                if (reg & kRegionBmo) m.bmo_volume_mm3 += ah;     // Eq. 8.11-8.12
                if (reg & kRegionDisc) m.total_volume_mm3 += ah;  // Eq. 8.14-8.15
                // Eq. 8.16-8.17 read as the annulus minus the cup (docs/algorithms/onh.md,
                // `annular_volume_mm3`).
                if ((reg & kRegionDisc) && !(reg & kRegionBmo)) m.annular_volume_mm3 += ah;
            }
        }
        m.face_region[static_cast<std::size_t>(f)] = reg;
    }
    return m;
}

OnhResult analyse_onh(const io::Scan& scan,
                      const IlmSurface& ilm,
                      const OnhParams& params,
                      const std::optional<std::vector<BmoPoint>>& bmo_file_points) {
    using namespace onh_detail;
    if (is_radial_scan(scan)) return analyse_onh_radial(scan, ilm, params, bmo_file_points);
    const auto t0 = std::chrono::steady_clock::now();
    params.validate();
    require_onh_volume(scan);
    OnhResult r;
    r.ilm_source = ilm.source;
    const ScanGeometry geo(scan);
    check_onh_inputs(scan, geo, ilm, r);
    GridSurface bm = bmo_points(scan, params, bmo_file_points, r);
    bmo_ellipse(params, r);
    rpe_surface(std::move(bm), r);
    const mesh::FaceGeometry g = orient_ilm(ilm, r);
    ilm_regions(ilm, params, r);
    centre_and_shape(g, params, r);
    minimum_rim_width(geo.scale_x_mm(), geo.distance_mm(), r);
    check_onh_result(r, scan);
    r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    return r;
}

namespace onh_detail {

double anatomical_deg(const OnhResult& r, double dx, double dy) {
    const Eigen::Vector2d a = r.grid_to_anatomical * Eigen::Vector2d(dx, dy);
    double deg = std::atan2(a.y(), a.x()) * 180.0 / kPi;
    if (deg < 0.0) deg += 360.0;
    if (deg >= 360.0) deg -= 360.0;
    return deg;
}

// Height of the topmost crossing of the vertical line through (x, y) with the mesh: what the
// line meets first coming from the vitreous (docs/algorithms/onh.md, `conht_mm`). NaN if it misses
// the mesh.
double top_crossing(const mesh::Vertices& V, const mesh::Faces& F, double x, double y) {
    double best = -std::numeric_limits<double>::infinity();
    for (Eigen::Index f = 0; f < F.rows(); ++f) {
        const Eigen::Vector3d a = V.row(F(f, 0));
        const Eigen::Vector3d b = V.row(F(f, 1));
        const Eigen::Vector3d c = V.row(F(f, 2));
        if (x < std::min({a.x(), b.x(), c.x()}) || x > std::max({a.x(), b.x(), c.x()}) ||
            y < std::min({a.y(), b.y(), c.y()}) || y > std::max({a.y(), b.y(), c.y()})) {
            continue;
        }
        const double det = (b.x() - a.x()) * (c.y() - a.y()) - (c.x() - a.x()) * (b.y() - a.y());
        if (std::fabs(det) < 1e-18) continue;  // vertical face: the line grazes it
        const double l1 = ((x - a.x()) * (c.y() - a.y()) - (c.x() - a.x()) * (y - a.y())) / det;
        const double l2 = ((b.x() - a.x()) * (y - a.y()) - (x - a.x()) * (b.y() - a.y())) / det;
        const double l0 = 1.0 - l1 - l2;
        const double eps = -1e-12;
        if (l0 < eps || l1 < eps || l2 < eps) continue;
        best = std::max(best, l0 * a.z() + l1 * b.z() + l2 * c.z());
    }
    return std::isfinite(best) ? best : kNaN;
}

void check_onh_result(const OnhResult& r, const io::Scan& scan) {
    check_onh_result(r, (scan.meta.size_x - 1) * scan.meta.scale_x_mm,
                     (scan.num_bscans() - 1) * scan.meta.distance_mm,
                     scan.meta.size_z * scan.meta.scale_z_mm);
}

void check_onh_result(const OnhResult& r, double width, double height, double depth) {
    const double field = width * height;
    auto fmt = [](double v) {
        std::ostringstream o;
        o.precision(4);
        o << v;
        return o.str();
    };
    auto refuse = [&](const std::string& what, double v, const std::string& possible) {
        throw AnalysisError("impossible result: " + what + " " + fmt(v) + " (possible: " +
                            possible + "); the scan is probably not of an optic nerve head, or "
                            "its segmentation is broken");
    };
    const BmoEllipse& e = r.ellipse;
    // Present: the BMO and the ILM surface always are, by now.
    for (const auto& [name, v] : {std::pair<const char*, double>{"BMO area (mm2)", e.area_mm2},
                                  {"BMO semi-major axis (mm)", e.semi_major_mm},
                                  {"BMO semi-minor axis (mm)", e.semi_minor_mm},
                                  {"BMO centre x (mm)", e.centre_mm.x()},
                                  {"BMO centre y (mm)", e.centre_mm.y()}}) {
        if (!std::isfinite(v)) refuse(name, v, "a finite number");
    }
    if (!(e.area_mm2 > 0.0) || e.area_mm2 > field) {
        refuse("BMO area (mm2)", e.area_mm2, "(0, " + fmt(field) + "], the scanned field");
    }
    if (2.0 * e.semi_major_mm > std::hypot(width, height)) {
        refuse("BMO major axis (mm)", 2.0 * e.semi_major_mm,
               "at most the field's diagonal " + fmt(std::hypot(width, height)));
    }
    if (e.centre_mm.x() < 0.0 || e.centre_mm.x() > width || e.centre_mm.y() < 0.0 ||
        e.centre_mm.y() > height) {
        refuse("BMO centre x (mm)", e.centre_mm.x(),
               "inside the field [0, " + fmt(width) + "] x [0, " + fmt(height) + "]");
    }
    // Volumes: between the ILM and the RPE, inside the scanned box. NaN = not measured.
    const double box = field * depth;
    for (const auto& [name, v] :
         {std::pair<const char*, double>{"cup volume (mm3)", r.cup_volume_mm3},
          {"BMO volume (mm3)", r.bmo_volume_mm3},
          {"total volume (mm3)", r.total_volume_mm3},
          {"annular volume (mm3)", r.annular_volume_mm3}}) {
        if (std::isinf(v) || (std::isfinite(v) && (v < 0.0 || v > box))) {
            refuse(name, v, "[0, " + fmt(box) + "], the scanned box");
        }
    }
    // Lengths within the image's depth (heights) or its diagonal (MRW, a 3-D distance).
    const double diagonal = std::sqrt(width * width + height * height + depth * depth);
    for (const auto& [name, v, limit] :
         {std::tuple<const char*, double, double>{"CONHT (mm)", std::fabs(r.conht_mm), depth},
          {"ILM height at the BMO centre (mm)", std::fabs(r.ilm_centre_height_mm), depth},
          {"RPE height at the BMO centre (mm)", std::fabs(r.rpe_centre_height_mm), depth},
          {"mean MRW (mm)", r.mrw_mean_mm, diagonal},
          {"minimum MRW (mm)", r.mrw_min_mm, diagonal},
          {"maximum MRW (mm)", r.mrw_max_mm, diagonal},
          {"mean in-plane MRW (mm)", r.mrw_inplane_mean_mm, diagonal},
          {"minimum in-plane MRW (mm)", r.mrw_inplane_min_mm, diagonal},
          {"maximum in-plane MRW (mm)", r.mrw_inplane_max_mm, diagonal}}) {
        if (std::isinf(v) || (std::isfinite(v) && (v < 0.0 || v > limit))) {
            refuse(name, v, "[0, " + fmt(limit) + "]");
        }
    }
    for (const double v : r.mrw_mm) {
        if (!std::isfinite(v) || v < 0.0 || v > diagonal) {
            refuse("MRW at a BMO point (mm)", v, "[0, " + fmt(diagonal) + "]");
        }
    }
    for (const InplaneMrw& m : r.mrw_inplane) {
        if (!std::isfinite(m.mrw_mm) || m.mrw_mm < 0.0 || m.mrw_mm > diagonal) {
            refuse("in-plane MRW at a BMO point (mm)", m.mrw_mm, "[0, " + fmt(diagonal) + "]");
        }
    }
    for (const auto& [name, v] :
         {std::pair<const char*, double>{"MRW area (mm2)", r.mrw_area_mm2},
          {"bending energy", r.bending_energy},
          {"ILM area inside the BMO (mm2)", r.bmo_region_area_mm2}}) {
        if (std::isinf(v) || (std::isfinite(v) && v < 0.0)) refuse(name, v, ">= 0, finite");
    }
}

void check_onh_inputs(const io::Scan& scan, const ScanGeometry& geo, const IlmSurface& ilm,
                      OnhResult& r) {
    r.eye = std::string(io::to_string(scan.meta.laterality));
    r.oriented_from_positions = geo.oriented_from_positions();
    r.grid_to_anatomical = geo.grid_to_anatomical();
    if (!geo.oriented_from_positions()) {
        r.notes.push_back(
            "B-scan positions unusable: assumed A-scans left to right, first B-scan inferior");
    }
    if (!geo.spacing().uniform || !geo.spacing().matches_header) {
        r.qc_flags.push_back("B-scan spacing not uniform or not matching the header Distance");
    }
    if (!geo.oriented_from_positions()) {
        r.qc_flags.push_back("orientation assumed (B-scan positions unusable)");
    }
    if (scan.meta.pattern == io::ScanPattern::kUnknown) {
        r.qc_flags.push_back("scan pattern unknown: analysed as a volume");
    }
    check_ilm_mesh(ilm);
}

void check_ilm_mesh(const IlmSurface& ilm) {
    if (ilm.F.rows() == 0) throw AnalysisError("the ILM surface has no faces");
    try {
        mesh::validate_mesh(ilm.V, ilm.F);
    } catch (const DataError& e) {
        throw AnalysisError(std::string("the ILM surface is not a valid mesh: ") + e.what());
    }
}

GridSurface bmo_points(const io::Scan& scan, const OnhParams& params,
                       const std::optional<std::vector<BmoPoint>>& file_points, OnhResult& r) {
    GridSurface bm = line_height_field(scan, io::Layer::kBM);
    if (std::all_of(bm.z.begin(), bm.z.end(), [](double v) { return std::isnan(v); })) {
        throw AnalysisError("the BM segmentation is missing everywhere");
    }
    if (file_points) {
        r.bmo_source = "file";
        r.bmo_measured = *file_points;
        return bm;
    }
    r.bmo_source = "automatic";
    BmoDetection det = detect_bmo_points(bm, params.detection);
    r.bmo_measured = std::move(det.points);
    r.bmo_points_per_bscan = std::move(det.points_per_bscan);
    r.bmo_gap_area_mm2 = det.gap_area_mm2;
    r.bmo_other_gaps = det.other_gaps;
    int single = 0;
    for (const int n : r.bmo_points_per_bscan) single += n == 1 ? 1 : 0;
    if (single > 0) {
        r.notes.push_back(std::to_string(single) +
                          " B-scans crossing the BM gap gave one BMO point only (the gap "
                          "reaches the scan edge or meets a missing neighbour)");
    }
    if (det.other_gaps > 0) {
        r.notes.push_back(std::to_string(det.other_gaps) + " smaller BM gaps (" +
                          std::to_string(det.other_gap_nodes) +
                          " A-scans) are not the disc and were ignored for the BMO");
    }
    return bm;
}

void bmo_ellipse(const OnhParams& params, OnhResult& r) {
    r.ellipse = fit_bmo_ellipse(r.bmo_measured, params.bmo_points);
    const BmoEllipse& E = r.ellipse;
    const double th = E.orientation_deg * kPi / 180.0;
    r.bmo_orientation_anatomical_deg =
        std::fmod(anatomical_deg(r, std::cos(th), std::sin(th)), 180.0);
    if (E.rms_residual_mm > 0.05) {
        r.qc_flags.push_back("BMO points lie " + fmt_mm(E.rms_residual_mm * 1000.0, 1) +
                             " um (RMS) from their ellipse");
    }
}

void rpe_surface(GridSurface bm, OnhResult& r, const std::vector<std::uint8_t>* scanned) {
    r.rpe = std::move(bm);
    const ThinPlateFillResult fill = thin_plate_fill(r.rpe);
    r.rpe_fill_residual = fill.residual;
    const double cell = r.rpe.dx_mm * r.rpe.dy_mm;
    r.rpe_filled_vertices = 0;
    r.rpe_fill_outside_bmo_mm2 = 0.0;
    for (int b = 0; b < r.rpe.rows; ++b) {
        for (int a = 0; a < r.rpe.cols; ++a) {
            const auto i = static_cast<std::size_t>(b) * static_cast<std::size_t>(r.rpe.cols) +
                           static_cast<std::size_t>(a);
            if (scanned != nullptr && !(*scanned)[i]) {
                // Outside the scanned area (radial: the circle the lines cover): no RPE.
                r.rpe.z[i] = kNaN;
                r.rpe.filled[i] = 0;
                continue;
            }
            if (!r.rpe.filled[i]) continue;
            ++r.rpe_filled_vertices;
            if (!r.ellipse.inside(a * r.rpe.dx_mm, b * r.rpe.dy_mm)) {
                r.rpe_fill_outside_bmo_mm2 += cell;
            }
        }
    }
    r.rpe_fill_area_mm2 = r.rpe_filled_vertices * cell;
    if (r.rpe_fill_outside_bmo_mm2 > 0.05 && scanned == nullptr) {
        r.qc_flags.push_back("BM missing outside the BMO ellipse: " +
                             fmt_mm(r.rpe_fill_outside_bmo_mm2, 3) + " mm2 filled");
    }
    if (scanned != nullptr) {
        graph_mesh_finite(r.rpe, r.rpe_V, r.rpe_F);
    } else {
        graph_mesh(r.rpe, r.rpe_V, r.rpe_F);
    }
}

mesh::FaceGeometry orient_ilm(const IlmSurface& ilm, OnhResult& r) {
    r.ilm_V = ilm.V;
    r.ilm_F = ilm.F;
    r.ilm_filled_vertices = ilm.filled_vertices;
    for (const auto& n : ilm.notes) r.notes.push_back(n);
    for (const auto& f : ilm.qc_flags) r.qc_flags.push_back(f);
    const Eigen::Index nf = r.ilm_F.rows();
    Eigen::VectorXd proj(nf);
    for (Eigen::Index f = 0; f < nf; ++f) {
        const Eigen::Vector3d a = r.ilm_V.row(r.ilm_F(f, 0));
        const Eigen::Vector3d b = r.ilm_V.row(r.ilm_F(f, 1));
        const Eigen::Vector3d c = r.ilm_V.row(r.ilm_F(f, 2));
        // Eq. 8.9: A_i = 1/2 (e0 x e1)_z of the projected triangle, signed.
        proj(f) = 0.5 * ((b.x() - a.x()) * (c.y() - a.y()) - (c.x() - a.x()) * (b.y() - a.y()));
    }
    if (proj.sum() < 0.0) {
        r.ilm_F.col(1).swap(r.ilm_F.col(2));
        r.ilm_flipped = true;
        proj = -proj;
    }
    r.face_projected_area_mm2 = proj;
    mesh::FaceGeometry g = mesh::face_geometry(r.ilm_V, r.ilm_F);
    r.ilm_quality = mesh_quality_report(r.ilm_V, r.ilm_F, g, proj);
    return g;
}

void ilm_regions(const IlmSurface& ilm, const OnhParams& params, OnhResult& r) {
    const Eigen::Vector2d c = r.ellipse.centre_mm;
    const double R = params.disc_radius_mm;
    OnhRegions m = measure_onh_regions(r.ilm_V, r.ilm_F, r.rpe, r.ellipse, R);
    r.face_height_mm = std::move(m.face_height_mm);
    r.face_region = std::move(m.face_region);
    r.faces_outside_rpe = m.faces_outside_rpe;
    r.cup_volume_mm3 = m.cup_volume_mm3;
    r.has_cup = m.cup_volume_mm3 > 0.0;
    r.bmo_volume_mm3 = m.bmo_volume_mm3;
    r.total_volume_mm3 = m.total_volume_mm3;
    r.annular_volume_mm3 = m.annular_volume_mm3;
    if (r.faces_outside_rpe > 0) {
        r.notes.push_back(std::to_string(r.faces_outside_rpe) +
                          " ILM faces lie outside the RPE grid and are in no region");
    }
    const double gx = (r.rpe.cols - 1) * r.rpe.dx_mm;
    const double gy = (r.rpe.rows - 1) * r.rpe.dy_mm;
    if (c.x() - R < 0.0 || c.y() - R < 0.0 || c.x() + R > gx || c.y() + R > gy) {
        r.qc_flags.push_back("the " + fmt_mm(R, 2) +
                             " mm disc around the BMO centre leaves the scan: total and "
                             "annular volumes are incomplete");
    }
    if (ilm.vertex_filled.size() == static_cast<std::size_t>(r.ilm_V.rows())) {
        for (Eigen::Index i = 0; i < r.ilm_V.rows(); ++i) {
            if (ilm.vertex_filled[static_cast<std::size_t>(i)] &&
                (Eigen::Vector2d(r.ilm_V(i, 0), r.ilm_V(i, 1)) - c).norm() <= R) {
                ++r.ilm_filled_in_disc;
            }
        }
    }
    if (r.ilm_filled_in_disc > 0) {
        r.qc_flags.push_back(std::to_string(r.ilm_filled_in_disc) +
                             " ILM vertices within the disc were filled (missing ILM)");
    }
}

void centre_and_shape(const mesh::FaceGeometry& g, const OnhParams& params, OnhResult& r) {
    // CONHT (Eq. 8.10).
    const Eigen::Vector2d c = r.ellipse.centre_mm;
    r.ilm_centre_height_mm = top_crossing(r.ilm_V, r.ilm_F, c.x(), c.y());
    r.rpe_centre_height_mm = r.rpe.bilinear(c.x(), c.y());
    r.conht_mm = r.ilm_centre_height_mm - r.rpe_centre_height_mm;
    if (std::isnan(r.conht_mm)) {
        r.qc_flags.push_back(
            "CONHT undefined: the vertical line through the BMO centre misses "
            "the ILM surface");
    }
    // Bending energy (Eq. 8.18-8.20: one area-weighted tensor of the BMO region).
    Eigen::Matrix3d M = Eigen::Matrix3d::Zero();
    double area = 0.0;
    for (Eigen::Index f = 0; f < r.ilm_F.rows(); ++f) {
        if (!(r.face_region[static_cast<std::size_t>(f)] & kRegionBmo)) continue;
        const Eigen::Vector3d n = g.normals.row(f);
        M += g.areas(f) * n * n.transpose();
        area += g.areas(f);
    }
    r.bmo_region_area_mm2 = area;
    if (area > 0.0) {
        M /= area;
        const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(M);
        const Eigen::Vector3d ev = eig.eigenvalues();  // ascending
        r.bmo_tensor_eigenvalues = {ev(2), ev(1), ev(0)};
        r.bending_energy = ev(0) + ev(1);  // lambda2 + lambda3
    } else {
        r.bmo_tensor_eigenvalues = {kNaN, kNaN, kNaN};
        r.bending_energy = kNaN;
        r.qc_flags.push_back("no ILM face inside the BMO: bending energy undefined");
    }
    if (params.local_features) {
        r.face_envt_strength = mesh::face_features(r.ilm_V, r.ilm_F).strength;
    }
}

void minimum_rim_width(double dx_mm, double dy_mm, OnhResult& r) {
    // Closest point on the ILM surface (Eq. 8.21-8.22).
    const BmoEllipse& E = r.ellipse;
    const Eigen::Vector2d c = E.centre_mm;
    const mesh::TriangleTree tree(r.ilm_V, r.ilm_F);
    const std::size_t np = E.points_mm.size();
    r.mrw_points_mm.resize(np);
    r.mrw_mm.resize(np);
    r.bmo_anatomical_deg.resize(np);
    std::array<double, 12> sector_sum{};
    r.mrw_sector_points = {};
    double sum = 0.0;
    r.mrw_min_mm = std::numeric_limits<double>::infinity();
    r.mrw_max_mm = 0.0;
    for (std::size_t i = 0; i < np; ++i) {
        const Eigen::Vector3d& p = E.points_mm[i];
        const mesh::SurfaceHit hit = tree.closest(p);
        r.mrw_points_mm[i] = hit.point;
        r.mrw_mm[i] = hit.distance;
        const double deg = anatomical_deg(r, p.x() - c.x(), p.y() - c.y());
        r.bmo_anatomical_deg[i] = deg;
        const std::size_t k = clock_hour(deg);
        sector_sum[k] += hit.distance;
        r.mrw_sector_points[k] += 1;
        sum += hit.distance;
        r.mrw_min_mm = std::min(r.mrw_min_mm, hit.distance);
        r.mrw_max_mm = std::max(r.mrw_max_mm, hit.distance);
    }
    r.mrw_mean_mm = sum / static_cast<double>(np);
    for (std::size_t k = 0; k < 12; ++k) {
        r.mrw_sector_mm[k] =
            r.mrw_sector_points[k] > 0 ? sector_sum[k] / r.mrw_sector_points[k] : kNaN;
    }
    // Eq. 8.23: quad i = (p_i, p_i+1, q_i+1, q_i), area = |d1 x d2| / 2 with its diagonals --
    // on the closest-point curve low-passed to kMrwAreaHarmonics harmonics: the closest points
    // on a rough (segmented, meshed) ILM jump between facets from one BMO point to the next,
    // and that jitter lengthens the strip's ILM edge without changing any MRW
    // (docs/algorithms/onh.md "MRW area").
    double perimeter = 0.0;
    for (std::size_t i = 0; i < np; ++i) {
        perimeter += (E.points_mm[(i + 1) % np] - E.points_mm[i]).norm();
    }
    const std::vector<Eigen::Vector3d> q = low_pass_closed_curve(
        r.mrw_points_mm, mrw_area_harmonics(perimeter, dx_mm, dy_mm));
    r.mrw_area_mm2 = 0.0;
    for (std::size_t i = 0; i < np; ++i) {
        const std::size_t j = (i + 1) % np;
        r.mrw_area_mm2 += 0.5 * (q[j] - E.points_mm[i]).cross(q[i] - E.points_mm[j]).norm();
    }
}

int mrw_area_harmonics(double bmo_perimeter_mm, double dx_mm, double dy_mm) {
    const double step = 4.0 * std::max(dx_mm, dy_mm);
    if (!(step > 0.0) || !std::isfinite(bmo_perimeter_mm)) return 8;
    return std::max(8, static_cast<int>(std::min(1e6, bmo_perimeter_mm / step)));
}

std::vector<Eigen::Vector3d> low_pass_closed_curve(const std::vector<Eigen::Vector3d>& c,
                                                   int harmonics) {
    const std::size_t n = c.size();
    if (harmonics < 0 || n <= static_cast<std::size_t>(2 * harmonics + 1)) return c;
    const double w = 2.0 * std::numbers::pi / static_cast<double>(n);
    std::vector<Eigen::Vector3d> out(n, Eigen::Vector3d::Zero());
    for (int k = 0; k <= harmonics; ++k) {
        Eigen::Vector3d a = Eigen::Vector3d::Zero();
        Eigen::Vector3d b = Eigen::Vector3d::Zero();
        for (std::size_t i = 0; i < n; ++i) {
            const double t = w * static_cast<double>(k) * static_cast<double>(i);
            a += c[i] * std::cos(t);
            b += c[i] * std::sin(t);
        }
        const double scale = (k == 0 ? 1.0 : 2.0) / static_cast<double>(n);
        for (std::size_t i = 0; i < n; ++i) {
            const double t = w * static_cast<double>(k) * static_cast<double>(i);
            out[i] += scale * (a * std::cos(t) + b * std::sin(t));
        }
    }
    return out;
}

}  // namespace onh_detail

}  // namespace octshape::retina
