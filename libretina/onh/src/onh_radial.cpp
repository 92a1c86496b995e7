// The ONH analysis on a radial scan (ScanPattern 5): the stages of onh_stages.h's "radial
// path". BMO points are the ends of the BM gap in each B-scan (two per line) or a file's points
// on their B-scans (read_radial_bmo_csv); the BM and the
// ILM are interpolated between the lines onto a square grid about the crossing, where the
// volume's stages measure the ellipse, volumes, CONHT, bending energy and the 3-D MRW; the
// in-plane MRW is measured on each B-scan's own ILM line. Decisions and measurements:
// docs/algorithms/onh.md "Radial scans".

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <numbers>
#include <sstream>

#include "octshape/error.h"
#include "octshape/retina/report_util.h"
#include "onh_stages.h"

namespace octshape::retina::onh_detail {
namespace {

constexpr double kPi = std::numbers::pi;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
// At most this many grid steps across the scanned circle's diameter (and never finer than the
// lines' A-scan spacing): the lines are 7.5 deg apart at 24 lines, 0.11 mm at the BMO, so a finer
// grid would only resample the interpolation; 256 keeps the thin-plate fill and the meshes of a
// 4.35 mm scan at ~0.017 mm (docs/algorithms/onh.md "Radial scans").
constexpr int kGridSteps = 256;
// Each half-line must reach this far from the crossing (mm): a BMO of the smallest plausible
// size (area 0.8 mm2, radius 0.5 mm) with BM on both sides.
constexpr double kMinRadiusMm = 0.5;

// Heights (mm, z = -depth ScaleZ) of segmentation line `layer` along B-scan `k`; NaN missing.
std::vector<double> line_heights(const io::Scan& scan, int k, io::Layer layer) {
    const int li = static_cast<int>(layer);
    const io::BScan& bs = scan.bscans[static_cast<std::size_t>(k)];
    if (!bs.has_line(li)) {
        throw AnalysisError("B-scan " + std::to_string(k) + " has no " + io::layer_name(li) +
                            " segmentation line");
    }
    const auto& line = bs.seg[static_cast<std::size_t>(li)];
    std::vector<double> z(static_cast<std::size_t>(scan.meta.size_x), kNaN);
    const std::size_t m = std::min(z.size(), line.size());
    for (std::size_t a = 0; a < m; ++a) {
        if (io::is_valid(line[a])) z[a] = -static_cast<double>(line[a]) * scan.meta.scale_z_mm;
    }
    return z;
}

// Linear interpolation of `z` at fractional index `a`; NaN outside or next to a missing value.
double at_fraction(const std::vector<double>& z, double a) {
    if (!(a >= -1e-9) || !(a <= static_cast<double>(z.size()) - 1.0 + 1e-9)) return kNaN;
    const int i = std::clamp(static_cast<int>(std::floor(a)), 0, static_cast<int>(z.size()) - 2);
    const double f = std::clamp(a - i, 0.0, 1.0);
    const double lo = z[static_cast<std::size_t>(i)];
    const double hi = z[static_cast<std::size_t>(i) + 1];
    if (f == 0.0) return lo;
    if (f == 1.0) return hi;
    return (1.0 - f) * lo + f * hi;
}

// Closest point of the polyline (s_a, z_a) (valid samples, consecutive A-scans) to (s, z).
// Returns {distance, s of the closest point, z of it}; distance NaN without a segment.
std::array<double, 3> closest_on_line(const std::vector<double>& z, double ds, double s0,
                                      double z0) {
    std::array<double, 3> best{kNaN, kNaN, kNaN};
    double best_d2 = std::numeric_limits<double>::infinity();
    for (std::size_t a = 0; a + 1 < z.size(); ++a) {
        if (std::isnan(z[a]) || std::isnan(z[a + 1])) continue;
        const double sa = static_cast<double>(a) * ds;
        const double es = ds;
        const double ez = z[a + 1] - z[a];
        const double t =
            std::clamp(((s0 - sa) * es + (z0 - z[a]) * ez) / (es * es + ez * ez), 0.0, 1.0);
        const double qs = sa + t * es;
        const double qz = z[a] + t * ez;
        const double d2 = (qs - s0) * (qs - s0) + (qz - z0) * (qz - z0);
        if (d2 < best_d2) {
            best_d2 = d2;
            best = {std::sqrt(d2), qs, qz};
        }
    }
    return best;
}

// Writes eye, orientation, the radial fields and the radial QC flags.
void radial_check(const io::Scan& scan, const RadialOnhGrid& grid, const IlmSurface& ilm,
                  OnhResult& r) {
    const RadialGeometry& g = grid.geo;
    r.eye = std::string(io::to_string(scan.meta.laterality));
    r.oriented_from_positions = true;
    r.grid_to_anatomical = g.radial_to_anatomical;
    r.radial = true;
    r.radial_lines = static_cast<int>(g.lines.size());
    r.radial_crossing_mm = grid.crossing_mm;
    r.radial_scanned_radius_mm = grid.radius_mm;
    r.radial_grid_step_mm = grid.step_mm;
    r.radial_max_miss_mm = g.max_miss_mm;
    r.radial_max_step_deg = g.max_step_deg;
    const RadialGeometryQc qc = radial_geometry_qc(g);
    r.qc_flags.insert(r.qc_flags.end(), qc.flags.begin(), qc.flags.end());
    r.notes.insert(r.notes.end(), qc.notes.begin(), qc.notes.end());
    if (scan.meta.laterality != io::Laterality::kOD && scan.meta.laterality != io::Laterality::kOS) {
        r.qc_flags.push_back("laterality unknown: nasal taken as SLO +x");
    }
    r.notes.push_back("radial scan: " + std::to_string(r.radial_lines) + " lines, surfaces "
                      "interpolated between them (linear in angle about the crossing) on a " +
                      fixed_number(grid.step_mm * 1e3, 1) + " um grid within " +
                      fixed_number(grid.radius_mm, 3) + " mm of the crossing");
    check_ilm_mesh(ilm);
}

// Returns the BM field on the grid; writes bmo_source, bmo_measured (the file's points when
// given), bmo_points_per_bscan, bmo_other_gaps and their notes. In each line the BMO is the run of missing BM that holds the
// crossing (else the longest), at least the diameter of a gap of min_gap_area_mm2; its ends
// as in detect_bmo_points: half an A-scan outside the last missing ones, the height
// extrapolated linearly by half an A-scan from the two present values outside.
GridSurface radial_bmo_points(const io::Scan& scan, const RadialOnhGrid& grid,
                              const OnhParams& params,
                              const std::optional<std::vector<BmoPoint>>& file_points,
                              OnhResult& r) {
    GridSurface bm = radial_height_field(scan, grid, io::Layer::kBM);
    if (file_points) {
        if (std::all_of(bm.z.begin(), bm.z.end(), [](double v) { return std::isnan(v); })) {
            throw AnalysisError("the BM segmentation is missing everywhere");
        }
        for (const BmoPoint& p : *file_points) {
            if (p.bscan < 0 || p.bscan >= static_cast<int>(grid.geo.lines.size())) {
                throw UsageError("radial scan: BMO file points must come from "
                                 "read_radial_bmo_csv (each with its B-scan)");
            }
        }
        r.bmo_source = "file";
        r.bmo_measured = *file_points;
        return bm;
    }
    r.bmo_source = "automatic";
    const int nx = grid.size_x;
    const int nl = static_cast<int>(grid.geo.lines.size());
    r.bmo_points_per_bscan.assign(static_cast<std::size_t>(nl), 0);
    bool any = false;
    int single = 0;
    const double min_diameter_mm = 2.0 * std::sqrt(params.detection.min_gap_area_mm2 / kPi);
    for (int k = 0; k < nl; ++k) {
        const std::vector<double> z = line_heights(scan, k, io::Layer::kBM);
        const RadialLine& line = grid.geo.lines[static_cast<std::size_t>(k)];
        const double ds = line.length_mm / (nx - 1);
        const double a_cross = line.crossing_along_mm / ds;
        // Runs of missing BM.
        int best0 = -1;
        int best1 = -1;
        bool best_holds = false;
        int runs = 0;
        for (int a = 0; a < nx;) {
            if (!std::isnan(z[static_cast<std::size_t>(a)])) {
                any = true;
                ++a;
                continue;
            }
            int e = a;
            while (e + 1 < nx && std::isnan(z[static_cast<std::size_t>(e) + 1])) ++e;
            ++runs;
            const bool holds = a - 0.5 <= a_cross && a_cross <= e + 0.5;
            const bool longer = e - a > best1 - best0;
            if ((e - a + 1) * ds >= min_diameter_mm &&
                (best0 < 0 || (holds && !best_holds) || (holds == best_holds && longer))) {
                best0 = a;
                best1 = e;
                best_holds = holds;
            }
            a = e + 1;
        }
        if (best0 < 0) {
            r.bmo_other_gaps += runs;
            continue;
        }
        r.bmo_other_gaps += runs - 1;
        auto add = [&](int outer, int outer2, double at, int side) {
            if (outer < 0 || outer >= nx || outer2 < 0 || outer2 >= nx) return;
            const double z1 = z[static_cast<std::size_t>(outer)];
            const double z2 = z[static_cast<std::size_t>(outer2)];
            if (std::isnan(z1) || std::isnan(z2)) return;
            BmoPoint p;
            const Eigen::Vector2d xy = grid.ascan_grid_mm(k, at);
            p.mm = {xy.x(), xy.y(), z1 + 0.5 * (z1 - z2)};
            p.bscan = k;
            p.side = side;
            r.bmo_measured.push_back(p);
            r.bmo_points_per_bscan[static_cast<std::size_t>(k)] += 1;
        };
        add(best0 - 1, best0 - 2, best0 - 0.5, -1);
        add(best1 + 1, best1 + 2, best1 + 0.5, +1);
        if (r.bmo_points_per_bscan[static_cast<std::size_t>(k)] == 1) ++single;
    }
    if (!any) throw AnalysisError("the BM segmentation is missing everywhere");
    if (r.bmo_measured.size() < 6) {
        throw AnalysisError("radial scan: " + std::to_string(r.bmo_measured.size()) +
                            " BMO points found (at least 6 are needed): no BM gap of the disc "
                            "in enough B-scans");
    }
    if (single > 0) {
        r.notes.push_back(std::to_string(single) +
                          " radial B-scans gave one BMO point only (the gap reaches the line's "
                          "end or meets missing BM)");
    }
    if (r.bmo_other_gaps > 0) {
        r.notes.push_back(std::to_string(r.bmo_other_gaps) +
                          " other BM gaps in the radial B-scans are not the disc and were "
                          "ignored for the BMO");
    }
    return bm;
}

// Closest point of the segments (s, z) to (s0, z0): {distance, s, z}; NaN without segments.
std::array<double, 3> closest_on_segments(const std::vector<PlaneSegment>& segs, double s0,
                                          double z0) {
    std::array<double, 3> best{kNaN, kNaN, kNaN};
    double best_d2 = std::numeric_limits<double>::infinity();
    for (const PlaneSegment& g : segs) {
        const double es = g.s1 - g.s0, ez = g.z1 - g.z0;
        const double len2 = es * es + ez * ez;
        const double t =
            len2 > 0.0 ? std::clamp(((s0 - g.s0) * es + (z0 - g.z0) * ez) / len2, 0.0, 1.0) : 0.0;
        const double qs = g.s0 + t * es;
        const double qz = g.z0 + t * ez;
        const double d2 = (qs - s0) * (qs - s0) + (qz - z0) * (qz - z0);
        if (d2 < best_d2) {
            best_d2 = d2;
            best = {std::sqrt(d2), qs, qz};
        }
    }
    return best;
}

// Writes mrw_inplane and its summaries: for each measured BMO point, the closest point of its
// B-scan's ILM curve in the B-scan's plane: the zero level of that B-scan's 2-D level set
// (ilm.bscan_curves) or, for the device ILM, the device line (the device's definition).
void inplane_rim_width(const io::Scan& scan, const RadialOnhGrid& grid, const IlmSurface& surf,
                       OnhResult& r) {
    const int nx = grid.size_x;
    const Eigen::Vector2d c = r.ellipse.centre_mm;
    std::array<double, 12> sum{};
    r.mrw_inplane_sector_points = {};
    double total = 0.0;
    int skipped = 0;
    std::vector<std::vector<double>> ilm(grid.geo.lines.size());
    for (const BmoPoint& p : r.bmo_measured) {
        const auto k = static_cast<std::size_t>(p.bscan);
        const bool curves = !surf.bscan_curves.empty();
        if (!curves && ilm[k].empty()) ilm[k] = line_heights(scan, p.bscan, io::Layer::kILM);
        const RadialLine& line = grid.geo.lines[k];
        const double ds = line.length_mm / (nx - 1);
        // The point's position along its line (it lies on it by construction).
        const Eigen::Vector2d start = grid.ascan_grid_mm(p.bscan, 0.0);
        const double s0 = (p.mm.head<2>() - start).norm();
        const auto [d, qs, qz] = curves ? closest_on_segments(surf.bscan_curves.at(k), s0, p.mm.z())
                                        : closest_on_line(ilm[k], ds, s0, p.mm.z());
        if (std::isnan(d)) {
            ++skipped;
            continue;
        }
        InplaneMrw m;
        m.bscan = p.bscan;
        m.side = p.side;
        m.bmo_mm = p.mm;
        const Eigen::Vector2d q = grid.ascan_grid_mm(p.bscan, qs / ds);
        m.ilm_mm = {q.x(), q.y(), qz};
        m.mrw_mm = d;
        m.anatomical_deg = anatomical_deg(r, p.mm.x() - c.x(), p.mm.y() - c.y());
        const std::size_t sector = clock_hour(m.anatomical_deg);
        sum[sector] += d;
        r.mrw_inplane_sector_points[sector] += 1;
        total += d;
        r.mrw_inplane.push_back(m);
    }
    if (skipped > 0) {
        r.notes.push_back(std::to_string(skipped) +
                          " BMO points have no ILM in their B-scan: no in-plane MRW there");
    }
    if (r.mrw_inplane.empty()) {
        r.qc_flags.push_back("no in-plane MRW: the ILM line is missing in every B-scan with a "
                             "BMO point");
        return;
    }
    r.mrw_inplane_mean_mm = total / static_cast<double>(r.mrw_inplane.size());
    r.mrw_inplane_min_mm = std::numeric_limits<double>::infinity();
    r.mrw_inplane_max_mm = 0.0;
    for (const InplaneMrw& m : r.mrw_inplane) {
        r.mrw_inplane_min_mm = std::min(r.mrw_inplane_min_mm, m.mrw_mm);
        r.mrw_inplane_max_mm = std::max(r.mrw_inplane_max_mm, m.mrw_mm);
    }
    for (std::size_t k = 0; k < 12; ++k) {
        r.mrw_inplane_sector_mm[k] = r.mrw_inplane_sector_points[k] > 0
                                         ? sum[k] / r.mrw_inplane_sector_points[k]
                                         : kNaN;
    }
}

}  // namespace

double RadialOnhGrid::half_line_ascan(int h, double r) const {
    const auto i = static_cast<std::size_t>(h);
    const RadialLine& l = geo.lines[static_cast<std::size_t>(half_line[i])];
    return (l.crossing_along_mm + half_sign[i] * r) * (size_x - 1) / l.length_mm;
}

RadialOnhGrid::Blend RadialOnhGrid::blend_at(const Eigen::Vector2d& p) const {
    const int nh = static_cast<int>(half_angle.size());
    double th = std::atan2(p.y(), p.x());
    if (th < 0.0) th += 2.0 * kPi;
    // Half-line j with a_j <= th < a_j+1 (cyclic).
    const auto it = std::upper_bound(half_angle.begin(), half_angle.end(), th);
    const int j1 = static_cast<int>(it - half_angle.begin()) % nh;
    const int j0 = (j1 + nh - 1) % nh;
    double a0 = half_angle[static_cast<std::size_t>(j0)];
    double a1 = half_angle[static_cast<std::size_t>(j1)];
    if (a1 <= a0) a1 += 2.0 * kPi;
    double t = th;
    if (t < a0) t += 2.0 * kPi;
    const double w = a1 > a0 ? std::clamp((t - a0) / (a1 - a0), 0.0, 1.0) : 0.0;
    return {j0, j1, w};
}

RadialOnhGrid radial_onh_grid(const io::Scan& scan) {
    if (!(scan.meta.scale_x_mm > 0.0) || !(scan.meta.scale_z_mm > 0.0) ||
        !std::isfinite(scan.meta.scale_z_mm)) {
        throw AnalysisError("the scan's ScaleX/ScaleZ are not positive");
    }
    if (scan.meta.size_x < 3) throw AnalysisError("radial B-scans of fewer than 3 A-scans");
    RadialOnhGrid g;
    g.geo = radial_geometry(scan);
    if (g.geo.lines.size() < 3) {
        throw AnalysisError("radial scan with " + std::to_string(g.geo.lines.size()) +
                            " lines: at least 3 are needed for the BMO ellipse");
    }
    g.size_x = scan.meta.size_x;
    g.radius_mm = std::numeric_limits<double>::infinity();
    for (const RadialLine& l : g.geo.lines) {
        g.radius_mm = std::min({g.radius_mm, l.crossing_along_mm, l.length_mm - l.crossing_along_mm});
    }
    if (!(g.radius_mm >= kMinRadiusMm)) {
        throw AnalysisError("radial scan whose lines reach only " + fixed_number(g.radius_mm, 3) +
                            " mm beyond their crossing (at least " + fixed_number(kMinRadiusMm, 1) +
                            " mm each side are needed)");
    }
    g.step_mm = std::max(g.geo.mean_length_mm / (g.size_x - 1), 2.0 * g.radius_mm / kGridSteps);
    const int half = static_cast<int>(std::ceil(g.radius_mm / g.step_mm - 1e-9));
    g.n = 2 * half + 1;
    g.crossing_mm = {half * g.step_mm, half * g.step_mm};
    g.scanned.assign(static_cast<std::size_t>(g.n) * static_cast<std::size_t>(g.n), 0);
    for (int b = 0; b < g.n; ++b) {
        for (int a = 0; a < g.n; ++a) {
            const Eigen::Vector2d p(a * g.step_mm, b * g.step_mm);
            if ((p - g.crossing_mm).norm() <= g.radius_mm * (1.0 + 1e-12)) {
                g.scanned[static_cast<std::size_t>(b) * static_cast<std::size_t>(g.n) +
                          static_cast<std::size_t>(a)] = 1;
            }
        }
    }
    // Half-lines by angle.
    std::vector<std::pair<double, std::pair<int, double>>> hl;
    for (int k = 0; k < static_cast<int>(g.geo.lines.size()); ++k) {
        const Eigen::Vector2d d = g.geo.direction(k);
        for (const double sign : {1.0, -1.0}) {
            double a = std::atan2(sign * d.y(), sign * d.x());
            if (a < 0.0) a += 2.0 * kPi;
            hl.push_back({a, {k, sign}});
        }
    }
    std::sort(hl.begin(), hl.end());
    for (const auto& [a, ks] : hl) {
        g.half_angle.push_back(a);
        g.half_line.push_back(ks.first);
        g.half_sign.push_back(ks.second);
    }
    return g;
}

GridSurface radial_height_field(const io::Scan& scan, const RadialOnhGrid& grid,
                                io::Layer layer) {
    const int nl = static_cast<int>(grid.geo.lines.size());
    std::vector<std::vector<double>> lines(static_cast<std::size_t>(nl));
    for (int k = 0; k < nl; ++k) lines[static_cast<std::size_t>(k)] = line_heights(scan, k, layer);
    GridSurface s;
    s.cols = grid.n;
    s.rows = grid.n;
    s.dx_mm = grid.step_mm;
    s.dy_mm = grid.step_mm;
    const auto nn = static_cast<std::size_t>(grid.n) * static_cast<std::size_t>(grid.n);
    s.z.assign(nn, kNaN);
    s.filled.assign(nn, 0);
    for (int b = 0; b < grid.n; ++b) {
        for (int a = 0; a < grid.n; ++a) {
            const std::size_t i = static_cast<std::size_t>(b) * static_cast<std::size_t>(grid.n) +
                                  static_cast<std::size_t>(a);
            if (!grid.scanned[i]) continue;
            const Eigen::Vector2d p = Eigen::Vector2d(a * grid.step_mm, b * grid.step_mm) -
                                      grid.crossing_mm;
            const double r = p.norm();
            const auto [j0, j1, w] = grid.blend_at(p);
            const double f0 = at_fraction(lines[static_cast<std::size_t>(
                                              grid.half_line[static_cast<std::size_t>(j0)])],
                                          grid.half_line_ascan(j0, r));
            const double f1 = at_fraction(lines[static_cast<std::size_t>(
                                              grid.half_line[static_cast<std::size_t>(j1)])],
                                          grid.half_line_ascan(j1, r));
            // Either neighbour missing (e.g. the BM gap ends between the two lines): NaN, for the
            // thin-plate fill. Taking the other line's value instead moves a sample by up to
            // r x the step (0.16 mm at 1.2 mm, 24 lines), ~10 um of BM height on the phantoms'
            // curved, tilted eye wall: the fill inside the BMO then came out 22 um off with the
            // crossing 300 um from the BMO centre (docs/algorithms/onh.md "Radial scans").
            s.z[i] = w == 0.0 ? f0 : w == 1.0 ? f1 : (1.0 - w) * f0 + w * f1;
        }
    }
    return s;
}

IlmSurface radial_device_ilm_surface(const io::Scan& scan) {
    const RadialOnhGrid grid = radial_onh_grid(scan);
    GridSurface s = radial_height_field(scan, grid, io::Layer::kILM);
    IlmSurface out;
    out.source = "device";
    int missing = 0;
    int scanned = 0;
    for (std::size_t i = 0; i < s.z.size(); ++i) {
        if (!grid.scanned[i]) continue;
        ++scanned;
        if (std::isnan(s.z[i])) ++missing;
    }
    if (missing == scanned) throw AnalysisError("the ILM segmentation is missing everywhere");
    if (missing > 0) {
        // Fill the scanned nodes' gaps (the fill also extends the field beyond the circle;
        // that part is dropped again).
        thin_plate_fill(s);
        for (std::size_t i = 0; i < s.z.size(); ++i) {
            if (!grid.scanned[i]) {
                s.z[i] = kNaN;
                s.filled[i] = 0;
            }
        }
        out.notes.push_back(std::to_string(missing) +
                            " grid nodes without a device ILM value (between the radial lines) "
                            "were thin-plate filled");
    }
    out.filled_vertices = missing;
    std::vector<int> node;
    graph_mesh_finite(s, out.V, out.F, &node);
    out.vertex_filled.resize(node.size());
    for (std::size_t v = 0; v < node.size(); ++v) {
        out.vertex_filled[v] = s.filled[static_cast<std::size_t>(node[v])];
    }
    return out;
}

OnhResult analyse_onh_radial(const io::Scan& scan, const IlmSurface& ilm,
                             const OnhParams& params,
                             const std::optional<std::vector<BmoPoint>>& bmo_file_points) {
    const auto t0 = std::chrono::steady_clock::now();
    params.validate();
    const RadialOnhGrid grid = radial_onh_grid(scan);
    OnhResult r;
    r.ilm_source = ilm.source;
    r.levelset_leak_bscans = ilm.leak_bscans;
    r.levelset_leak_fallback_ascans = ilm.leak_fallback_ascans;
    r.levelset_leak_cut_ascans = ilm.leak_cut_ascans;
    radial_check(scan, grid, ilm, r);
    GridSurface bm = radial_bmo_points(scan, grid, params, bmo_file_points, r);
    bmo_ellipse(params, r);
    rpe_surface(std::move(bm), r, &grid.scanned);
    const mesh::FaceGeometry g = orient_ilm(ilm, r);
    ilm_regions(ilm, params, r);
    const double leave = (r.ellipse.centre_mm - grid.crossing_mm).norm() + params.disc_radius_mm;
    if (leave > grid.radius_mm) {
        r.qc_flags.push_back("the " + fixed_number(params.disc_radius_mm, 2) +
                             " mm disc around the BMO centre leaves the scanned circle (radius " +
                             fixed_number(grid.radius_mm, 2) +
                             " mm): total and annular volumes are incomplete");
    }
    centre_and_shape(g, params, r);
    // The MRW area's resolution: along the lines their A-scan spacing, across them the arc
    // between neighbouring lines at the BMO.
    const double bmo_radius = std::sqrt(r.ellipse.semi_major_mm * r.ellipse.semi_minor_mm);
    minimum_rim_width(grid.geo.mean_length_mm / (grid.size_x - 1),
                      bmo_radius * grid.geo.max_step_deg * kPi / 180.0, r);
    inplane_rim_width(scan, grid, ilm, r);
    const double side = (grid.n - 1) * grid.step_mm;
    check_onh_result(r, side, side, scan.meta.size_z * scan.meta.scale_z_mm);
    r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    return r;
}

}  // namespace octshape::retina::onh_detail

namespace octshape::retina {

std::vector<BmoPoint> read_radial_bmo_csv(const std::string& path, const io::Scan& scan) {
    const onh_detail::RadialOnhGrid grid = onh_detail::radial_onh_grid(scan);
    // Read in index units (x = A-scan, y = B-scan, z = -depth px): read_bmo_csv's range check
    // is then the scan's A-scan and B-scan ranges.
    io::ScanMeta units = scan.meta;
    units.scale_x_mm = 1.0;
    units.distance_mm = 1.0;
    units.scale_z_mm = 1.0;
    bool pixel_header = false;
    std::vector<BmoPoint> pts = read_bmo_csv(path, units, scan.num_bscans(), &pixel_header);
    if (!pixel_header) {
        throw InputError::corrupt(path, "a radial scan's BMO file needs the header "
                                        "'ascan,bscan,depth_px' (each point on its B-scan)");
    }
    for (BmoPoint& p : pts) {
        const double b = std::round(p.mm.y());
        if (std::fabs(p.mm.y() - b) > 1e-9) {
            throw InputError::corrupt(path, "a BMO point's bscan is not a whole number");
        }
        const int k = static_cast<int>(b);
        const Eigen::Vector2d xy = grid.ascan_grid_mm(k, p.mm.x());
        p.mm = {xy.x(), xy.y(), p.mm.z() * scan.meta.scale_z_mm};
        p.bscan = k;
        p.side = 0;
    }
    return pts;
}

}  // namespace octshape::retina
