// ETDRS sectors and the device's thickness grid (etdrs.h, docs/algorithms/etdrs.md).

#include "octshape/retina/etdrs.h"

#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <numbers>
#include <sstream>
#include <utility>

#include "cube_stages.h"
#include "octshape/error.h"

namespace octshape::retina {
namespace {

using V2 = Eigen::Vector2d;
constexpr double kPi = std::numbers::pi;

// The device's cells C0, N1, N2, S1, S2, T1, T2, I1, I2 -> kEtdrsSectorNames order (central,
// inner S N I T, outer S N I T).
constexpr std::array<int, kEtdrsSectors> kFromDeviceOrder = {0, 3, 1, 7, 5, 4, 2, 8, 6};

std::string fixed(double v, int digits) {
    std::ostringstream s;
    s.setf(std::ios::fixed);
    s.precision(digits);
    s << v;
    return s.str();
}

// Thickness along a line scan at grid x (linear between A-scans), NaN outside or missing.
double line_thickness(const ThicknessMap& m, double x_mm) { return m.sample(x_mm, 0.0); }

}  // namespace

void EtdrsParams::validate() const {
    const auto& d = diameters_mm;
    if (!(d[0] > 0.0 && d[0] < d[1] && d[1] < d[2] && d[2] <= 12.0)) {
        throw UsageError("ETDRS diameters must increase within (0, 12] mm");
    }
    if (!(step_mm >= 0.001 && step_mm <= 0.05)) {
        throw UsageError("ETDRS quadrature step must be within [0.001, 0.05] mm");
    }
    // Every border must be a whole number of steps, so that the rings fall on it.
    for (const double v : d) {
        const double k = 0.5 * v / step_mm;
        if (std::fabs(k - std::round(k)) > 1e-6) {
            throw UsageError("ETDRS radii must be whole multiples of the quadrature step");
        }
    }
    if (!(min_coverage > 0.0 && min_coverage <= 1.0)) {
        throw UsageError("ETDRS min_coverage must be within (0, 1]");
    }
}

EtdrsGrid etdrs_grid(const ThicknessMap& m,
                     const ScanGeometry& geo,
                     const Eigen::Vector2d& centre_mm,
                     const EtdrsParams& p) {
    p.validate();
    if (m.rows < 2) throw AnalysisError("ETDRS sectors need a volume scan (this is one line)");
    EtdrsGrid g;
    g.centre_mm = centre_mm;
    g.centre_thickness_mm = m.sample(centre_mm.x(), centre_mm.y());
    // Anatomical (nasal, superior) offsets -> grid offsets.
    const Eigen::Matrix2d to_grid = geo.grid_to_anatomical().inverse();
    const double r1 = 0.5 * p.diameters_mm[0];
    const double r2 = 0.5 * p.diameters_mm[1];
    const double r3 = 0.5 * p.diameters_mm[2];
    const int rings = static_cast<int>(std::lround(r3 / p.step_mm));
    std::array<double, kEtdrsSectors> sum{};       // integral of T over the measured part
    std::array<double, kEtdrsSectors> measured{};  // measured area
    std::array<double, kEtdrsSectors> area{};      // the sector's whole area (as integrated)
    for (int i = 0; i < rings; ++i) {
        const double ra = i * p.step_mm;
        const double rb = (i + 1) * p.step_mm;
        const double r = 0.5 * (ra + rb);
        // Arcs of at most one step, a multiple of 4 per ring so that the rays at +-45 deg (the
        // quadrants' borders) fall between samples.
        const int quads = std::max(1, static_cast<int>(std::ceil(2.0 * kPi * r / (4.0 * p.step_mm))));
        const int n = 4 * quads;
        const double dtheta = 2.0 * kPi / n;
        const double cell = 0.5 * (rb * rb - ra * ra) * dtheta;  // exact area of the cell
        const bool central = rb <= r1 + 1e-12;
        const int ring = rb <= r2 + 1e-12 ? 0 : 1;
        for (int j = 0; j < n; ++j) {
            // From -45 deg (the nasal quadrant's first border), anatomical.
            const double theta = -0.25 * kPi + (j + 0.5) * dtheta;
            const int quadrant = j / quads;  // 0 nasal, 1 superior, 2 temporal, 3 inferior
            int s = 0;
            if (!central) {
                // kEtdrsSectorNames: 1 + 4 ring + (superior 0, nasal 1, inferior 2, temporal 3).
                static constexpr std::array<int, 4> kQuadrantSlot = {1, 0, 3, 2};
                s = 1 + 4 * ring + kQuadrantSlot[static_cast<std::size_t>(quadrant)];
            }
            const auto k = static_cast<std::size_t>(s);
            area[k] += cell;
            const V2 q = centre_mm + to_grid * V2(r * std::cos(theta), r * std::sin(theta));
            const double t = m.sample(q.x(), q.y());
            if (std::isnan(t)) continue;
            sum[k] += t * cell;
            measured[k] += cell;
        }
    }
    double total = 0.0;
    double all_area = 0.0;
    double all_measured = 0.0;
    bool all = true;
    for (std::size_t k = 0; k < area.size(); ++k) {
        EtdrsSector& s = g.sectors[k];
        s.coverage = measured[k] / area[k];
        all_area += area[k];
        all_measured += measured[k];
        if (s.coverage >= p.min_coverage) {
            s.thickness_mm = sum[k] / measured[k];
            s.volume_mm3 = s.thickness_mm * area[k];
            total += s.volume_mm3;
        } else {
            all = false;
        }
    }
    g.coverage = all_measured / all_area;
    if (all) g.total_volume_mm3 = total;
    return g;
}

std::optional<DeviceEtdrs> device_etdrs(const io::Scan& scan, const ScanGeometry& geo) {
    for (const io::ThicknessGrid& grid : scan.grids) {
        if (!grid.is_circular() || grid.cells.size() != static_cast<std::size_t>(kEtdrsSectors)) {
            continue;
        }
        DeviceEtdrs d;
        d.type = grid.type;
        d.diameters_mm = grid.diameters_mm;
        d.centre_mm = geo.slo_to_grid(V2(grid.centre_x_slo_mm, grid.centre_y_slo_mm));
        if (scan.num_bscans() == 1) {
            // A line scan's grid x is the projection on the line; y its distance from it.
            d.centre_off_scan_mm = std::fabs(d.centre_mm.y());
            d.centre_mm.y() = 0.0;
        }
        d.central_thickness_mm = grid.central_thickness_mm;
        for (std::size_t k = 0; k < kFromDeviceOrder.size(); ++k) {
            const auto& c = grid.cells[static_cast<std::size_t>(kFromDeviceOrder[k])];
            d.thickness_mm[k] = c.thickness_mm;
            d.volume_mm3[k] = c.volume_mm3;
        }
        d.total_volume_mm3 = grid.total_volume_mm3;
        return d;
    }
    return std::nullopt;
}

ThicknessMap layer_thickness_map(const io::Scan& scan, std::string_view upper,
                                 std::string_view lower) {
    const auto u = scan.find_line(upper);
    const auto l = scan.find_line(lower);
    if (!u || !l) {
        throw AnalysisError("the scan has no line named '" + std::string(!u ? upper : lower) +
                            "' (for the ETDRS thickness)");
    }
    return cube_detail::thickness_map_of_lines(scan, *u, *l);
}

EtdrsReport etdrs_report(const io::Scan& scan,
                         const CubeResult& res,
                         const EtdrsParams& p,
                         std::string_view upper,
                         std::string_view lower) {
    p.validate();
    EtdrsReport out;
    out.params = p;
    out.upper_layer = std::string(upper);
    out.lower_layer = std::string(lower);
    out.line_scan = res.line_scan;
    const ScanGeometry geo(scan);
    const bool retina = scan.find_line(upper) == std::optional<int>(0) &&
                        scan.find_line(lower) == std::optional<int>(1);
    const ThicknessMap other = retina ? ThicknessMap{} : layer_thickness_map(scan, upper, lower);
    const ThicknessMap& m = retina ? res.map : other;
    if (res.radial_scan) {
        // The map's rows are lines 7.5-30 deg apart, not a grid: nothing to integrate between
        // them yet.
        out.notes.push_back("ETDRS sectors are not computed on radial scans");
        return out;
    }
    out.device = device_etdrs(scan, geo);
    if (!res.line_scan) {
        out.at_fovea = etdrs_grid(m, geo, res.centre_mm, p);
        if (out.device) out.at_device = etdrs_grid(m, geo, out.device->centre_mm, p);
        // The raster's middle in grid mm (nodes at 0 ... (cols - 1) dx and (rows - 1) dy).
        const Eigen::Vector2d scan_centre(0.5 * (m.cols - 1) * m.dx_mm, 0.5 * (m.rows - 1) * m.dy_mm);
        out.at_scan_centre = etdrs_grid(m, geo, scan_centre, p);
        for (const auto& [g, where] :
             {std::pair{&out.at_fovea, "(fovea centre)"}, std::pair{&out.at_device, "(device centre)"},
              std::pair{&out.at_scan_centre, "(scan centre)"}}) {
            if (!*g) continue;
            for (std::size_t k = 0; k < kEtdrsSectorNames.size(); ++k) {
                if (std::isnan((**g).sectors[k].thickness_mm)) {
                    out.notes.push_back("ETDRS " + std::string(kEtdrsSectorNames[k]) + " sector " +
                                        where + " is " +
                                        fixed(100.0 * (**g).sectors[k].coverage, 0) +
                                        " % measured: not reported");
                }
            }
        }
    }
    // The device's own numbers beside ours (the retina only: the device's grid is ILM-BM).
    if (out.device && retina) {
        const DeviceEtdrs& d = *out.device;
        out.ours_at_device_centre_mm = res.line_scan ? line_thickness(m, d.centre_mm.x())
                                                     : m.sample(d.centre_mm.x(), d.centre_mm.y());
        if (std::isfinite(d.central_thickness_mm) && std::isfinite(out.ours_at_device_centre_mm)) {
            out.central_difference_um = 1e3 * (out.ours_at_device_centre_mm - d.central_thickness_mm);
            // Reported as a QC value, not a flag: what the device calls its central thickness,
            // and from which data it computed it, are not documented (docs/algorithms/etdrs.md
            // "Against the device": on the real line scan it is not this B-scan's).
        }
        if (res.line_scan && d.centre_off_scan_mm > 0.5 * scan.meta.scale_x_mm) {
            out.notes.push_back("the device grid centre lies " + fixed(1e3 * d.centre_off_scan_mm, 0) +
                                " um off the line: compared at its projection");
        }
    }
    return out;
}

}  // namespace octshape::retina
