// ETDRS sectors (retina/etdrs.h) against the macula phantoms' generating thickness T(r, theta)
// (phantom_macula.h), integrated here by Gauss-Legendre quadrature over each sector, independent
// of the analysis's polar midpoint grid and of the map's interpolation.

#include "octshape/retina/etdrs.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numbers>

#include "octshape/error.h"
#include "octshape/io/scan_reader.h"
#include "octshape/io/topcon.h"
#include "octshape/retina/phantom_macula.h"
#include "test_paths.h"

namespace octshape::retina {
namespace {

using V2 = Eigen::Vector2d;
constexpr double kPi = std::numbers::pi;

// 16-point Gauss-Legendre nodes and weights on [-1, 1].
constexpr std::array<double, 8> kGlX = {0.0950125098376374, 0.2816035507792589, 0.4580167776572274,
                                        0.6178762444026438, 0.7554044083550030, 0.8656312023878318,
                                        0.9445750230732326, 0.9894009349916499};
constexpr std::array<double, 8> kGlW = {0.1894506104550685, 0.1826034150449236, 0.1691565193950025,
                                        0.1495959888165767, 0.1246289712555339, 0.0951585116824928,
                                        0.0622535239386479, 0.0271524594117541};

// Integral of f over [a, b]: 16-point Gauss-Legendre on `panels` panels.
template <class F>
double gauss(F f, double a, double b, int panels) {
    double sum = 0.0;
    const double h = (b - a) / panels;
    for (int p = 0; p < panels; ++p) {
        const double m = a + (p + 0.5) * h;
        for (std::size_t i = 0; i < kGlX.size(); ++i) {
            const double d = 0.5 * h * kGlX[i];
            sum += 0.5 * h * kGlW[i] * (f(m - d) + f(m + d));
        }
    }
    return sum;
}

// Sector k of kEtdrsSectorNames: radii and anatomical angles (deg).
struct SectorShape {
    double r0, r1, t0, t1;
};
SectorShape sector_shape(std::size_t k) {
    if (k == 0) return {0.0, 0.5, 0.0, 360.0};
    const double r0 = k <= 4 ? 0.5 : 1.5;
    const double r1 = k <= 4 ? 1.5 : 3.0;
    // superior, nasal, inferior, temporal: centred on 90, 0, 270, 180 deg.
    static constexpr std::array<double, 4> kCentre = {90.0, 0.0, 270.0, 180.0};
    const double c = kCentre[(k - 1) % 4];
    return {r0, r1, c - 45.0, c + 45.0};
}

// T at grid point q of the phantom (its generating surface; polar about the true centre).
double truth_at(const MaculaPhantomParams& p, const MaculaPhantom& ph, const V2& q) {
    const V2 d = q - ph.centre_mm;
    return macula_thickness_mm(p, d.norm(), ph.frame.anatomical_angle_deg(d.x(), d.y()));
}

// Mean of T over sector k of a grid centred at `c` (grid mm), by Gauss-Legendre in r and theta.
double truth_mean(const MaculaPhantomParams& p, const MaculaPhantom& ph, const V2& c,
                  std::size_t k) {
    const SectorShape s = sector_shape(k);
    auto ring = [&](double r) {
        return r * gauss(
                       [&](double tdeg) {
                           const V2 q = c + r * ph.frame.grid_direction(tdeg);
                           return truth_at(p, ph, q);
                       },
                       s.t0, s.t1, 12) *
               kPi / 180.0;
    };
    const double integral = gauss(ring, s.r0, s.r1, 12);
    const double area = 0.5 * (s.r1 * s.r1 - s.r0 * s.r0) * (s.t1 - s.t0) * kPi / 180.0;
    return integral / area;
}

// The bilinear interpolant of nodes dx, dy apart errs by at most (dx^2 max|T_xx| + dy^2
// max|T_yy|) / 8 at any point (tensor-product linear interpolation); a mean over a sector errs
// by at most the largest such bound over the cells it touches. The second derivatives are
// measured on the generating surface by central differences (h = 2 um) at 8 um steps over the
// sector widened by one cell. 8 um (a quarter of the cost of 4 um, which cost ~1 s a test): the
// phantoms' T'' varies over their pits' handles (alpha 0.26 mm, beta 0.55 mm), so the sampled
// maximum misses the true one by a few percent at most (the 36 sector bounds of these tests
// moved by 0 to -2.4 % from 4 to 8 um), and the bound, the worst point's error applied to the
// whole sector, is 10-100x the errors measured.
double bilinear_bound(const MaculaPhantomParams& p, const MaculaPhantom& ph, const V2& c,
                      std::size_t k, double dx, double dy) {
    constexpr double grid = 0.008;
    const SectorShape s = sector_shape(k);
    const double margin = std::hypot(dx, dy);
    constexpr double h = 0.002;
    double txx = 0.0;
    double tyy = 0.0;
    const double rmax = s.r1 + margin;
    for (double x = -rmax; x <= rmax; x += grid) {
        for (double y = -rmax; y <= rmax; y += grid) {
            const V2 q = c + V2(x, y);
            const double r = std::hypot(x, y);
            if (r > rmax || r < std::max(0.0, s.r0 - margin)) continue;
            if (k != 0) {
                // Within the quadrant's angles, widened by the margin's angle at this radius.
                const V2 a = ph.frame.grid_to_anatomical * V2(x, y);
                double t = std::atan2(a.y(), a.x()) * 180.0 / kPi;
                const double mid = 0.5 * (s.t0 + s.t1);
                double off = std::fmod(t - mid + 540.0, 360.0) - 180.0;
                const double widen = r > 0 ? std::asin(std::min(1.0, margin / r)) * 180.0 / kPi : 180.0;
                if (std::fabs(off) > 45.0 + widen) continue;
            }
            const double t0 = truth_at(p, ph, q);
            txx = std::max(txx, std::fabs(truth_at(p, ph, q + V2(h, 0)) - 2 * t0 +
                                          truth_at(p, ph, q - V2(h, 0))) / (h * h));
            tyy = std::max(tyy, std::fabs(truth_at(p, ph, q + V2(0, h)) - 2 * t0 +
                                          truth_at(p, ph, q - V2(0, h))) / (h * h));
        }
    }
    return (dx * dx * txx + dy * dy * tyy) / 8.0;
}

struct Case {
    MaculaFamily family;
    io::Laterality eye;
    int bscans;
};

class EtdrsPhantom : public ::testing::TestWithParam<Case> {};

TEST_P(EtdrsPhantom, SectorsMatchDenseQuadratureOfTheGeneratingSurface) {
    const Case cs = GetParam();
    MaculaPhantomParams p;
    p.family = cs.family;
    p.eye = cs.eye;
    p.num_bscans = cs.bscans;
    p.pixels = false;
    p.fovea_dx_mm = 0.0237;  // off the grid nodes
    p.fovea_dy_mm = -0.0311;
    const MaculaPhantom ph = make_macula_phantom(p);
    const ThicknessMap m = thickness_map(ph.scan);
    const ScanGeometry geo(ph.scan);
    const EtdrsGrid g = etdrs_grid(m, geo, ph.centre_mm);
    double worst = 0.0;
    for (std::size_t k = 0; k < kEtdrsSectorNames.size(); ++k) {
        const double truth = truth_mean(p, ph, ph.centre_mm, k);
        const double bound = bilinear_bound(p, ph, ph.centre_mm, k, m.dx_mm, m.dy_mm);
        // The polar midpoint grid's own error (10 um rings, arcs <= 10 um: ~ step^2 |T''| / 24,
        // below 0.01 um) and float rounding of the stored depths (< 1e-4 um) are far below the
        // interpolation bound; 0.05 um covers them.
        const double tol = bound + 5e-5;
        const EtdrsSector& s = g.sectors[k];
        ASSERT_NEAR(s.coverage, 1.0, 1e-12) << kEtdrsSectorNames[k];
        EXPECT_NEAR(s.thickness_mm, truth, tol)
            << kEtdrsSectorNames[k] << " bound " << 1e3 * bound << " um";
        worst = std::max(worst, std::fabs(s.thickness_mm - truth) / tol);
        std::printf("%-15s truth %.5f ours %.5f diff %+.3f um bound %.3f um\n",
                    std::string(kEtdrsSectorNames[k]).c_str(), truth, s.thickness_mm,
                    1e3 * (s.thickness_mm - truth), 1e3 * bound);
    }
    // The volumes are the means times the exact sector areas.
    EXPECT_NEAR(g.sectors[0].volume_mm3, g.sectors[0].thickness_mm * kPi * 0.25, 1e-12);
    double total = 0.0;
    for (const auto& s : g.sectors) total += s.volume_mm3;
    EXPECT_NEAR(g.total_volume_mm3, total, 1e-12);
    // The test discriminates: swapping nasal and temporal (a laterality mistake) or superior
    // and inferior would move the inner sectors by more than the tolerance (at 61 B-scans; at
    // 25 the interpolation bound is larger than the phantom's asymmetry).
    const double dn = std::fabs(truth_mean(p, ph, ph.centre_mm, 2) - truth_mean(p, ph, ph.centre_mm, 4));
    const double ds = std::fabs(truth_mean(p, ph, ph.centre_mm, 1) - truth_mean(p, ph, ph.centre_mm, 3));
    const double inner_bound = bilinear_bound(p, ph, ph.centre_mm, 2, m.dx_mm, m.dy_mm);
    if (cs.bscans == 61) {
        EXPECT_GT(dn, 2.0 * inner_bound) << "nasal-temporal difference " << 1e3 * dn << " um";
        EXPECT_GT(ds, 2.0 * inner_bound) << "superior-inferior difference " << 1e3 * ds << " um";
    }
    RecordProperty("worst_over_tolerance", std::to_string(worst));
}

INSTANTIATE_TEST_SUITE_P(
    Eyes, EtdrsPhantom,
    ::testing::Values(Case{MaculaFamily::kBezier, io::Laterality::kOD, 61},
                      Case{MaculaFamily::kBezier, io::Laterality::kOS, 61},
                      Case{MaculaFamily::kScheibe, io::Laterality::kOD, 61},
                      Case{MaculaFamily::kScheibe, io::Laterality::kOS, 25}),
    [](const ::testing::TestParamInfo<Case>& i) {
        return to_string(i.param.family) + "_" + std::string(io::to_string(i.param.eye)) + "_" +
               std::to_string(i.param.bscans);
    });

TEST(Etdrs, DeviceGridIsComparedSectorBySector) {
    // The phantom stores a device-like grid 50 um from the fovea: its cells are the generating
    // surface's sector means by a coarse midpoint rule (60 rings x 72 rays), in the file's order
    // C0, N1, N2, S1, S2, T1, T2, I1, I2. Read in our order, each cell must match the dense
    // truth of the same sector at that centre, and ours at the device centre must match it.
    MaculaPhantomParams p;
    p.pixels = false;
    p.eye = io::Laterality::kOS;
    const MaculaPhantom ph = make_macula_phantom(p);
    const CubeResult res = analyse_macula(ph.scan);
    const EtdrsReport r = etdrs_report(ph.scan, res);
    ASSERT_TRUE(r.device.has_value());
    ASSERT_TRUE(r.at_device.has_value());
    ASSERT_TRUE(r.at_fovea.has_value());
    EXPECT_EQ(r.at_fovea->centre_mm, res.centre_mm);
    const V2 hint = ph.centre_mm + V2(p.grid_hint_dx_mm, p.grid_hint_dy_mm);
    EXPECT_NEAR((r.device->centre_mm - hint).norm(), 0.0, 1e-6);
    const ThicknessMap m = thickness_map(ph.scan);
    for (std::size_t k = 0; k < kEtdrsSectorNames.size(); ++k) {
        const double truth = truth_mean(p, ph, hint, k);
        // The coarse midpoint rule errs by ~ h^2 |T''| / 24 per direction (h = 50 um radially:
        // 1e-4 mm^2 x |T''| <= 2 /mm -> 0.01 um; 5 deg of arc: the same order; the pit's
        // curvature makes the central disk's the largest, 0.13 um measured); the float cells
        // add 3e-5 um. 0.5 um separates the sectors: their truths differ by more than twice
        // that (checked below), so a cell read into the wrong sector fails.
        EXPECT_NEAR(r.device->thickness_mm[k], truth, 5e-4) << kEtdrsSectorNames[k];
        const double bound = bilinear_bound(p, ph, hint, k, m.dx_mm, m.dy_mm);
        EXPECT_NEAR(r.at_device->sectors[k].thickness_mm, truth, bound + 5e-5)
            << kEtdrsSectorNames[k];
        std::printf("%-15s device %.5f truth %.5f ours %.5f\n",
                    std::string(kEtdrsSectorNames[k]).c_str(), r.device->thickness_mm[k], truth,
                    r.at_device->sectors[k].thickness_mm);
    }
    // Every pair of sectors of the same ring differs by more than 1 um in truth here, so the
    // 0.5 um test above tells the sectors apart.
    for (std::size_t i = 1; i < kEtdrsSectorNames.size(); ++i) {
        for (std::size_t j = i + 1; j < kEtdrsSectorNames.size(); ++j) {
            if ((i <= 4) != (j <= 4)) continue;
            EXPECT_GT(std::fabs(truth_mean(p, ph, hint, i) - truth_mean(p, ph, hint, j)), 1e-3)
                << kEtdrsSectorNames[i] << " " << kEtdrsSectorNames[j];
        }
    }
}

// The grid at the scan centre (the raster's middle, where a device puts the fixation target
// and centres its own grid when it has no fovea finder) on an eye whose fovea is 0.6 mm nasal
// and 0.45 mm inferior of it, as a Heidelberg .vol (in memory) and as a Topcon .fda (written
// and read back: B-scan 0 is inferior there, so a mistaken row order would swap superior and
// inferior). Each sector against the dense quadrature of the generating surface about the scan
// centre, which is known independently: the phantom's fovea minus its offset. Depth pixels of
// 1 um (not 3.87) so that the .fda's whole-pixel contours cost at most 1 um (below).
TEST(Etdrs, GridAtTheScanCentreOfAnEyeWhoseFoveaIsOffIt) {
    MaculaPhantomParams p;
    p.pixels = false;
    p.eye = io::Laterality::kOD;  // grid +x nasal
    p.fovea_dx_mm = 0.6;
    p.fovea_dy_mm = -0.45;
    p.scale_z_mm = 0.001;
    p.size_z = 1920;  // the 496 x 3.87 um of the default depth
    const MaculaPhantom ph = make_macula_phantom(p);
    const V2 scan_centre = ph.centre_mm - V2(p.fovea_dx_mm, p.fovea_dy_mm);
    const ThicknessMap m = thickness_map(ph.scan);
    std::array<double, kEtdrsSectors> truth{};
    std::array<double, kEtdrsSectors> bound{};
    for (std::size_t k = 0; k < kEtdrsSectorNames.size(); ++k) {
        truth[k] = truth_mean(p, ph, scan_centre, k);
        bound[k] = bilinear_bound(p, ph, scan_centre, k, m.dx_mm, m.dy_mm);
    }
    // The test tells apart what it guards against: the grid at the fovea (central subfield
    // 0.268 against 0.325 mm here), superior and inferior swapped (inner ring, 28 um apart),
    // nasal and temporal swapped (outer ring, 60 um apart); each by more than twice the
    // largest tolerance below (bound + 1 um).
    const double fovea_central = truth_mean(p, ph, ph.centre_mm, 0);
    EXPECT_GT(std::fabs(fovea_central - truth[0]), 2.0 * (bound[0] + 1e-3));
    EXPECT_GT(std::fabs(truth[1] - truth[3]), 2.0 * (std::max(bound[1], bound[3]) + 1e-3));
    EXPECT_GT(std::fabs(truth[6] - truth[8]), 2.0 * (std::max(bound[6], bound[8]) + 1e-3));
    test::TempDir dir;
    const std::string fda = (dir / "off.fda").string();
    io::write_topcon_file(ph.scan, fda);
    const io::Scan topcon = io::read_scan(fda);
    for (const io::Scan* scan : {&ph.scan, &topcon}) {
        const bool is_fda = scan == &topcon;
        SCOPED_TRACE(is_fda ? "Topcon .fda" : "Heidelberg .vol");
        const CubeResult res = analyse_macula(*scan);
        const EtdrsReport r = etdrs_report(*scan, res);
        ASSERT_TRUE(r.at_scan_centre.has_value());
        EXPECT_NEAR((r.at_scan_centre->centre_mm - scan_centre).norm(), 0.0, 1e-9);
        for (std::size_t k = 0; k < kEtdrsSectorNames.size(); ++k) {
            // .vol: the interpolation bound plus 0.05 um (quadrature and float depths, as in
            // SectorsMatchDenseQuadratureOfTheGeneratingSurface). .fda: its contours are whole
            // pixels, each surface rounded by at most half a pixel, so a node's thickness by at
            // most one pixel (1 um) and a sector's mean by no more.
            const double tol = bound[k] + (is_fda ? p.scale_z_mm : 5e-5);
            const EtdrsSector& s = r.at_scan_centre->sectors[k];
            EXPECT_NEAR(s.thickness_mm, truth[k], tol) << kEtdrsSectorNames[k];
            std::printf("%s %-15s truth %.5f ours %.5f diff %+.3f um tol %.3f um\n",
                        is_fda ? "fda" : "vol", std::string(kEtdrsSectorNames[k]).c_str(),
                        truth[k], s.thickness_mm, 1e3 * (s.thickness_mm - truth[k]), 1e3 * tol);
        }
    }
}

TEST(Etdrs, LineScanHasNoSectorsButTheDeviceCentre) {
    SKIP_UNLESS_SHARED("realdata/fovea_line_716_0.vol");
    const io::Scan scan = io::read_scan(test::realdata("fovea_line_716_0.vol").string());
    const CubeResult res = analyse_macula(scan);
    const EtdrsReport r = etdrs_report(scan, res);
    EXPECT_FALSE(r.at_fovea.has_value());
    EXPECT_FALSE(r.at_device.has_value());
    ASSERT_TRUE(r.device.has_value());
    std::printf("device central %.4f mm, ours at its centre %.4f mm, difference %+.2f um, "
                "centre %.1f um off the line\n",
                r.device->central_thickness_mm, r.ours_at_device_centre_mm,
                r.central_difference_um, 1e3 * r.device->centre_off_scan_mm);
    // The realdata README: central thickness 0.2178 mm at the grid centre.
    EXPECT_NEAR(r.device->central_thickness_mm, 0.2178, 5e-5);
    // Ours at the centre is the line's own thickness there, read here from the depths: the
    // centre's A-scan (x - StartX) / ScaleX, linear between its two neighbours.
    const io::BScan& b = scan.bscans[0];
    const double fa = (scan.grids[0].centre_x_slo_mm - b.start_x_mm) / scan.meta.scale_x_mm;
    const int a0 = static_cast<int>(std::floor(fa));
    auto th = [&](int a) {
        return (scan.depth_px(1, 0, a) - scan.depth_px(0, 0, a)) * scan.meta.scale_z_mm;
    };
    const double expected = th(a0) + (fa - a0) * (th(a0 + 1) - th(a0));
    EXPECT_NEAR(r.ours_at_device_centre_mm, expected, 1e-9);
    // The device's number does not come from this B-scan's segmentation: its minimum central
    // thickness (within 0.5 mm of the centre) is below the line's own minimum there by 0.8 px,
    // which no interpolation of the line can give. So a one-pixel agreement at the centre
    // cannot be required of the line (measured +5.27 um = 1.36 px); the difference is
    // reported as a value, never a flag (docs/algorithms/etdrs.md).
    double line_min = 1e9;
    for (int a = 0; a < scan.meta.size_x; ++a) {
        if (std::fabs(a - fa) * scan.meta.scale_x_mm <= 0.5 && !std::isnan(th(a))) {
            line_min = std::min(line_min, th(a));
        }
    }
    std::printf("device min central %.4f mm, the line's minimum within 0.5 mm %.4f mm\n",
                scan.grids[0].min_central_thickness_mm, line_min);
    EXPECT_LT(scan.grids[0].min_central_thickness_mm, line_min - scan.meta.scale_z_mm * 0.75);
    EXPECT_TRUE(r.qc_flags.empty());
}

TEST(Etdrs, BadParametersAreUsageErrors) {
    EtdrsParams p;
    p.diameters_mm = {1.0, 0.5, 6.0};
    EXPECT_THROW(p.validate(), UsageError);
    p = {};
    p.min_coverage = 0.0;
    EXPECT_THROW(p.validate(), UsageError);
    p = {};
    p.step_mm = 0.007;  // 0.5 mm is not a whole number of steps
    EXPECT_THROW(p.validate(), UsageError);
}

}  // namespace
}  // namespace octshape::retina
