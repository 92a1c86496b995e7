// CuBe fovea analysis (retina/cube.h) against closed forms, dense numerics and the macula
// phantoms, whose truth comes from the generating functions (phantom_macula.h), not from cube.

#include "octshape/retina/cube.h"

#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numbers>
#include <vector>

#include "octshape/error.h"
#include "octshape/io/scan_reader.h"
#include "octshape/retina/phantom_macula.h"
#include "retina/macula_bounds.h"
#include "test_paths.h"
#include "slow_test.h"

namespace octshape::retina {
namespace {

using V2 = Eigen::Vector2d;
using Ctrl = std::array<V2, 4>;
constexpr double kDeg = 180.0 / std::numbers::pi;

Ctrl interior_curve(double cft, double w, double h, double alpha, double beta) {
    return {V2(0.0, cft), V2(alpha, cft), V2(w - beta, h), V2(w, h)};
}

// Samples of a curve at equal x steps (x monotone), found by bisection on x(t).
std::vector<V2> sample_by_x(const Ctrl& c, int n) {
    std::vector<V2> out;
    for (int k = 0; k <= n; ++k) {
        const double x = c[0].x() + (c[3].x() - c[0].x()) * k / n;
        out.push_back(bezier_point(c, bezier_t_at_x(c, x)));
    }
    return out;
}

TEST(CubeMaxSlope, ClosedFormMatchesDenseEvaluation) {
    // docs/algorithms/cube.md `max_pit_slope_deg`: s = dy / (sqrt(ab) + w - a - b) at t_m = sqrt(a)
    // / (sqrt(a) + sqrt(b)). The dense maximum of y'(t)/x'(t) over 200 000 steps is independent of
    // that derivation; the slope is flat at its maximum, so a t-step of 5e-6 changes it by ~1e-10
    // relative.
    const std::array<std::array<double, 5>, 5> cases{{{0.225, 1.1, 0.35, 0.26, 0.55},
                                                      {0.2, 0.9, 0.33, 0.05, 0.8},
                                                      {0.24, 1.3, 0.36, 0.6, 0.4},
                                                      {0.22, 1.0, 0.3, 0.5, 0.5},
                                                      {0.21, 1.2, 0.37, 0.01, 0.02}}};
    for (const auto& cs : cases) {
        const Ctrl c = interior_curve(cs[0], cs[1], cs[2], cs[3], cs[4]);
        double best = 0.0;
        double best_t = 0.0;
        constexpr int kSteps = 200000;
        for (int i = 1; i < kSteps; ++i) {
            const double t = static_cast<double>(i) / kSteps;
            const V2 d = bezier_derivative(c, t);
            if (d.y() / d.x() > best) {
                best = d.y() / d.x();
                best_t = t;
            }
        }
        const MaxSlope m = interior_max_slope(c);
        EXPECT_NEAR(m.slope, best, 1e-9 * best) << cs[3] << " " << cs[4];
        EXPECT_NEAR(m.t, best_t, 1e-3) << cs[3] << " " << cs[4];
        // The thesis' printed Eq. 7.20 (-dy / (a - b - sqrt(ab) - w)) differs whenever a != b.
        const double printed =
            -(cs[2] - cs[0]) / (cs[3] - cs[4] - std::sqrt(cs[3] * cs[4]) - cs[1]);
        if (std::fabs(cs[3] - cs[4]) > 0.05) {
            EXPECT_GT(std::fabs(printed - best), 1e-3);
        }
    }
}

TEST(CubeVolume, ExactPolynomialIntegralMatchesSimpson) {
    // Simpson with 20 000 intervals on a degree-8 integrand: error ~ h^4 f'''' ~ 1e-17.
    const Ctrl c{V2(0.0, 0.22), V2(0.3, 0.22), V2(0.6, 0.37), V2(1.2, 0.31)};
    for (const double t1 : {1.0, 0.37}) {
        constexpr int kN = 20000;
        double sum = 0.0;
        for (int i = 0; i <= kN; ++i) {
            const double t = t1 * i / kN;
            const double f =
                bezier_point(c, t).y() * bezier_point(c, t).x() * bezier_derivative(c, t).x();
            sum += f * ((i == 0 || i == kN) ? 1.0 : (i % 2 == 1 ? 4.0 : 2.0));
        }
        EXPECT_NEAR(bezier_volume_integral(c, t1), sum * t1 / kN / 3.0, 1e-13);
    }
}

TEST(CubeFit, FittedThicknessFollowsEachSegmentAndIsMissingOutside) {
    // A half-line whose interior runs to the rim at r = 1.1 mm and whose exterior runs on to
    // R = 2 mm: at a point of each curve (found by bisection on x(t), sample_by_x) the fitted
    // thickness is that point's height to the bisection's last bit (1e-12 mm); the rim lies on
    // both; outside [0, R] and on an invalid half-line there is none.
    CubeHalfLine h;
    h.valid = true;
    h.r_mm = {0.0, 1.0, 2.0};
    h.interior.control = interior_curve(0.22, 1.1, 0.35, 0.3, 0.4);
    h.exterior.control = {V2(1.1, 0.35), V2(1.4, 0.35), V2(1.7, 0.31), V2(2.0, 0.30)};
    for (const Ctrl* c : {&h.interior.control, &h.exterior.control}) {
        for (const V2& p : sample_by_x(*c, 7)) {
            EXPECT_NEAR(fitted_thickness_mm(h, p.x()), p.y(), 1e-12) << p.x();
        }
    }
    EXPECT_NEAR(fitted_thickness_mm(h, 1.1), 0.35, 1e-12);
    EXPECT_TRUE(std::isnan(fitted_thickness_mm(h, -1e-9)));
    EXPECT_TRUE(std::isnan(fitted_thickness_mm(h, 2.0 + 1e-9)));
    h.valid = false;
    EXPECT_TRUE(std::isnan(fitted_thickness_mm(h, 0.5)));
}

TEST(CubeFit, InteriorAndExteriorRecoverExactCurves) {
    // Samples lie exactly on a CuBe curve: the least-squares minimum is that curve (energy 0),
    // so control points come back to rounding and the RMSE is ~0.
    const Ctrl in = interior_curve(0.225, 1.1, 0.35, 0.26, 0.55);
    const BezierFit fi = fit_interior(sample_by_x(in, 94));
    EXPECT_TRUE(fi.converged);
    EXPECT_NEAR(fi.control[1].x(), 0.26, 1e-9);
    EXPECT_NEAR(fi.control[2].x(), 1.1 - 0.55, 1e-9);
    EXPECT_LT(std::sqrt(fi.sse_mm2 / fi.num_samples), 1e-9);
    const Ctrl ex{V2(1.1, 0.35), V2(1.4, 0.35), V2(1.7, 0.27), V2(2.0, 0.29)};
    const BezierFit fe = fit_exterior(sample_by_x(ex, 77));
    EXPECT_NEAR(fe.control[1].x(), 1.4, 1e-8);
    EXPECT_NEAR(fe.control[2].x(), 1.7, 1e-8);
    EXPECT_NEAR(fe.control[2].y(), 0.27, 1e-8);
    EXPECT_LT(std::sqrt(fe.sse_mm2 / fe.num_samples), 1e-9);
}

TEST(CubeFit, RimProfileRecoversExactCurvesWithTheRimHeightFree) {
    // Interior and exterior exactly of the CuBe form, sharing the rim (1.1, 0.35), sampled at
    // equal x steps with the rim a sample: the joint fit (rim height free, Eq. 7.8 over both
    // segments) has its zero-energy minimum at the generating curves and starts there.
    const Ctrl in = interior_curve(0.225, 1.1, 0.35, 0.26, 0.55);
    const Ctrl ex{V2(1.1, 0.35), V2(1.4, 0.35), V2(1.7, 0.27), V2(2.0, 0.29)};
    std::vector<V2> d = sample_by_x(in, 94);
    const std::vector<V2> e = sample_by_x(ex, 77);
    d.insert(d.end(), e.begin() + 1, e.end());
    const RimProfileFit f = fit_rim_profile(d, 94);
    EXPECT_TRUE(f.converged);
    EXPECT_NEAR(f.rim.x(), 1.1, 1e-15);
    EXPECT_NEAR(f.rim.y(), 0.35, 1e-9);
    EXPECT_NEAR(f.interior.control[1].x(), 0.26, 1e-8);
    EXPECT_NEAR(f.interior.control[2].x(), 1.1 - 0.55, 1e-8);
    EXPECT_NEAR(f.exterior.control[1].x(), 1.4, 1e-8);
    EXPECT_NEAR(f.exterior.control[2].x(), 1.7, 1e-8);
    EXPECT_NEAR(f.exterior.control[2].y(), 0.27, 1e-8);
    EXPECT_EQ(f.interior.num_samples + f.exterior.num_samples, static_cast<int>(d.size()));
    EXPECT_LT(std::sqrt((f.interior.sse_mm2 + f.exterior.sse_mm2) / d.size()), 1e-9);
}

TEST(CubeFit, FittedRimRecoversARimBetweenSamples) {
    // The same two curves sampled on a uniform x grid that steps over the rim (1.1 lies 5 % of
    // a step past sample 94). RimPoint::kCrest: the rim radius is an unknown of the joint fit, so
    // the zero-energy minimum is again the generating pair, found from the start at the maximum
    // sample (foot points converge to ~1e-9). kMaximum keeps the junction at that sample and
    // cannot reach zero energy: its rim sits on the sample, ~0.6 um of radius off.
    const Ctrl in = interior_curve(0.225, 1.1, 0.35, 0.26, 0.55);
    const Ctrl ex{V2(1.1, 0.35), V2(1.4, 0.35), V2(1.7, 0.27), V2(2.0, 0.29)};
    const int n = 171;
    const double h = 2.0 / n;
    std::vector<V2> d;
    for (int k = 0; k <= n; ++k) {
        const double x = k * h;
        const Ctrl& c = x <= 1.1 ? in : ex;
        double lo = 0.0;
        double hi = 1.0;
        for (int i = 0; i < 200 && hi - lo > 1e-16; ++i) {
            const double mid = 0.5 * (lo + hi);
            (bezier_point(c, mid).x() < x ? lo : hi) = mid;
        }
        d.push_back(bezier_point(c, 0.5 * (lo + hi)));
    }
    int rim = 1;
    for (int k = 1; k <= n; ++k) {
        if (d[static_cast<std::size_t>(k)].y() > d[static_cast<std::size_t>(rim)].y()) rim = k;
    }
    ASSERT_GT(std::fabs(d[static_cast<std::size_t>(rim)].x() - 1.1), 1e-4);
    FitSettings fit;
    fit.rim_point = RimPoint::kCrest;
    const RimProfileFit f = fit_rim_profile(d, rim, fit);
    EXPECT_NEAR(f.rim.x(), 1.1, 1e-7);
    EXPECT_NEAR(f.rim.y(), 0.35, 1e-9);
    EXPECT_NEAR(f.interior.control[1].x(), 0.26, 1e-6);
    EXPECT_NEAR(f.exterior.control[2].x(), 1.7, 1e-6);
    EXPECT_LT(std::sqrt((f.interior.sse_mm2 + f.exterior.sse_mm2) / d.size()), 1e-8);
    FitSettings max;
    max.rim_point = RimPoint::kMaximum;
    const RimProfileFit m = fit_rim_profile(d, rim, max);
    EXPECT_EQ(m.rim.x(), d[static_cast<std::size_t>(rim)].x());
    EXPECT_GT(std::sqrt((m.interior.sse_mm2 + m.exterior.sse_mm2) / d.size()), 1e-8);
}

TEST(CubeFit, RimHeightIsNotTheBiasedMaximumSample) {
    // The same profile with a deterministic +-3 um alternating perturbation (zero mean): the
    // maximum sample sits ~3 um above the crest, the joint least-squares rim height averages
    // the ~40 samples near the crest and stays within 1 um (3 um / sqrt(40) ~ 0.5 um, x2).
    const Ctrl in = interior_curve(0.225, 1.1, 0.35, 0.26, 0.55);
    const Ctrl ex{V2(1.1, 0.35), V2(1.4, 0.35), V2(1.7, 0.27), V2(2.0, 0.29)};
    std::vector<V2> d = sample_by_x(in, 94);
    const std::vector<V2> e = sample_by_x(ex, 77);
    d.insert(d.end(), e.begin() + 1, e.end());
    for (std::size_t k = 1; k + 1 < d.size(); ++k) d[k].y() += (k % 2 == 0 ? 0.003 : -0.003);
    const int rim = 94;
    ASSERT_GT(d[rim].y(), 0.3525);  // the rim sample itself is 3 um high
    const RimProfileFit f = fit_rim_profile(d, rim);
    EXPECT_NEAR(f.rim.y(), 0.35, 0.001);
}

TEST(CubeFit, CovarianceLeavesAHandleOnItsBoundFree) {
    // The pit rises from the centre like a cone (+0.2 mm per mm for the first 0.1 mm, fading
    // to 0 at the rim, on top of a CuBe interior with alpha = 0): the fit's alpha wants to be
    // negative and rests on its bound alpha >= 0. The noise terms' covariance
    // (FitSettings::covariance) must not pin it there: under noise whether a handle rests on its
    // bound changes from realisation to realisation, and a pinned alpha has no variance and no
    // covariance with the rim (docs/algorithms/cube.md, "Session 46"). Before, alpha's row and
    // column were exactly 0.
    const Ctrl in = interior_curve(0.225, 1.1, 0.35, 0.0, 0.55);
    const Ctrl ex{V2(1.1, 0.35), V2(1.4, 0.35), V2(1.7, 0.27), V2(2.0, 0.29)};
    std::vector<V2> d = sample_by_x(in, 94);
    for (std::size_t k = 1; k < d.size(); ++k) {
        d[k].y() += 0.2 * std::min(d[k].x(), 0.1) * (1.0 - d[k].x() / 1.1);
    }
    const std::vector<V2> e = sample_by_x(ex, 77);
    d.insert(d.end(), e.begin() + 1, e.end());
    for (std::size_t k = 1; k + 1 < d.size(); ++k) d[k].y() += (k % 2 == 0 ? 0.001 : -0.001);
    FitSettings fit;
    fit.covariance = true;
    fit.crest_tolerance_mm = 0.005;  // the crest's bounds on r_rim, pinned when active, inactive
    const RimProfileFit f = fit_rim_profile(d, 94, fit);
    ASSERT_EQ(f.interior.control[1].x(), f.interior.control[0].x());  // alpha on its bound
    const Eigen::Matrix4d& c = f.interior_cov;
    ASSERT_TRUE(c.allFinite());
    EXPECT_GT(c(0, 0), 0.0);
    EXPECT_GT(Eigen::SelfAdjointEigenSolver<Eigen::Matrix4d>(c).eigenvalues().minCoeff(), 0.0);
}

TEST(CubeFit, InteriorStaysAGraph) {
    // A step-like profile wants alpha + beta > w; the constraint keeps the curve a graph.
    std::vector<V2> step;
    for (int k = 0; k <= 40; ++k) {
        const double x = 0.025 * k;
        step.emplace_back(x, x < 0.5 ? 0.2 : 0.35);
    }
    step.back() = V2(1.0, 0.35);
    const BezierFit f = fit_interior(step);
    const double a = f.control[1].x() - f.control[0].x();
    const double b = f.control[3].x() - f.control[2].x();
    EXPECT_GE(a, 0.0);
    EXPECT_GE(b, 0.0);
    EXPECT_LE(a + b, 1.0 + 1e-12);
    for (int i = 1; i <= 1000; ++i) EXPECT_GE(bezier_derivative(f.control, i / 1000.0).x(), 0.0);
}

TEST(CubeParams, ValidateNamesTheField) {
    CubeParams p;
    EXPECT_NO_THROW(p.validate());
    p.num_half_lines = 23;
    try {
        p.validate();
        FAIL();
    } catch (const UsageError& e) {
        EXPECT_NE(std::string(e.what()).find("num_half_lines"), std::string::npos);
    }
    p = {};
    p.inner_radius_mm = 3.0;
    EXPECT_THROW(p.validate(), UsageError);
    p = {};
    p.tau_mm = 0.0;
    EXPECT_THROW(p.validate(), UsageError);
    p = {};
    p.local_fit_min_noise_um = std::numeric_limits<double>::quiet_NaN();
    try {
        p.validate();
        FAIL();
    } catch (const UsageError& e) {
        EXPECT_NE(std::string(e.what()).find("local_fit_min_noise_um"), std::string::npos);
    }
    p.local_fit_min_noise_um = std::numeric_limits<double>::infinity();  // always bilinear
    EXPECT_NO_THROW(p.validate());
}

TEST(CubeThicknessMap, BilinearExactOnPlanesAndMissingRespected) {
    ThicknessMap m;
    m.rows = 3;
    m.cols = 4;
    m.dx_mm = 0.01;
    m.dy_mm = 0.1;
    for (int b = 0; b < 3; ++b) {
        for (int a = 0; a < 4; ++a) m.mm.push_back(0.2 + 0.5 * a * 0.01 - 0.3 * b * 0.1);
    }
    EXPECT_NEAR(m.sample(0.017, 0.13), 0.2 + 0.5 * 0.017 - 0.3 * 0.13, 1e-15);
    EXPECT_NEAR(m.sample(0.03, 0.2), 0.2 + 0.5 * 0.03 - 0.3 * 0.2, 1e-15);  // far corner
    EXPECT_TRUE(std::isnan(m.sample(0.031, 0.1)));                          // outside
    m.mm[5] = kMissing;                                                     // node (b 1, a 1)
    EXPECT_TRUE(std::isnan(m.sample(0.005, 0.05)));
    EXPECT_TRUE(std::isnan(m.sample(0.015, 0.15)));
    EXPECT_FALSE(std::isnan(m.sample(0.025, 0.05)));
}

// ---- phantoms ---------------------------------------------------------------------------------

MaculaPhantomParams volume_params(MaculaFamily f, int bscans, bool flat = false) {
    MaculaPhantomParams p;
    p.family = f;
    p.flat = flat;
    p.num_bscans = bscans;
    p.pixels = false;
    // Off every grid node so that the sampling error is not artificially zero.
    p.fovea_dx_mm = 0.0237;
    p.fovea_dy_mm = -0.0311;
    return p;
}

struct Errors {
    double centre = 0, cft = 0, rim_height = 0, rim_diameter = 0, rim_area_rel = 0,
           slope_diameter = 0, slope_deg = 0, flat_diameter = 0, vr_rel = 0, vir_rel = 0,
           vp_rel = 0, alpha = 0, beta = 0, rmse_um = 0;
};

Errors errors(const CubeResult& r, const MaculaPhantom& ph) {
    const MaculaTruth& t = ph.truth;
    Errors e;
    e.centre = (r.centre_mm - ph.centre_mm).norm();
    e.cft = std::fabs(r.cft_mm - t.cft_mm);
    e.rim_height = std::fabs(r.rim_height_mm - t.rim_height_mm);
    e.rim_diameter = std::fabs(r.rim.diameter_mm - t.rim.diameter_mm);
    e.rim_area_rel = std::fabs(r.rim.area_mm2 / t.rim.area_mm2 - 1.0);
    e.slope_diameter = std::fabs(r.slope.diameter_mm - t.slope.diameter_mm);
    e.slope_deg = std::fabs(r.max_pit_slope_deg - t.max_pit_slope_deg);
    e.flat_diameter = std::fabs(r.pit_flat_diameter_mm - t.pit_flat_diameter_mm);
    e.vr_rel = std::fabs(r.rim_volume_mm3 / t.rim_volume_mm3 - 1.0);
    e.vir_rel = std::fabs(r.inner_rim_volume_mm3 / t.inner_rim_volume_mm3 - 1.0);
    e.vp_rel = std::fabs(r.pit_volume_mm3 / t.pit_volume_mm3 - 1.0);
    if (t.alpha_mean_mm) e.alpha = std::fabs(r.alpha_mean_mm - *t.alpha_mean_mm);
    if (t.beta_mean_mm) e.beta = std::fabs(r.beta_mean_mm - *t.beta_mean_mm);
    e.rmse_um = r.rmse_um;
    return e;
}

void record(const std::string& tag, const Errors& e) {
    ::testing::Test::RecordProperty(
        tag,
        "centre " + std::to_string(e.centre * 1e3) + " um, cft " + std::to_string(e.cft * 1e3) +
            " um, rim_h " + std::to_string(e.rim_height * 1e3) + " um, rim_d " +
            std::to_string(e.rim_diameter * 1e3) + " um, slope " + std::to_string(e.slope_deg) +
            " deg, slope_d " + std::to_string(e.slope_diameter * 1e3) + " um, flat_d " +
            std::to_string(e.flat_diameter * 1e3) + " um, Vr " + std::to_string(e.vr_rel * 100) +
            " %, Vir " + std::to_string(e.vir_rel * 100) + " %, Vp " +
            std::to_string(e.vp_rel * 100) + " %, rmse " + std::to_string(e.rmse_um) + " um");
}

// Slow: full-size phantom volumes (up to 401 x 768): seconds under the sanitizers.
SLOW_TEST(CubePhantom, BezierIdealSamplingFitsExactly) {
    // Ideal sampling: an isotropic grid (Distance = ScaleX = 11.69 um, 401 B-scans over
    // 4.68 mm) and the analysis started from the true centre. Bilinear interpolation then errs
    // by <= (2 dx^2) max|T''| / 8 = 0.06 um (max |T''| ~ 1.8 /mm in the pit), the only error
    // left: the model represents the surface exactly.
    MaculaPhantomParams p = volume_params(MaculaFamily::kBezier, 401);
    p.distance_mm = 0.01169;
    p.scale_x_mm = 0.01169;
    const MaculaPhantom ph = make_macula_phantom(p);
    CubeParams cp;
    cp.centre_mm = ph.centre_mm;
    const CubeResult r = analyse_macula(ph.scan, cp);
    const SamplingBounds sb = sampling_bounds(p, 0.01169, 0.01169, 0.0);
    ASSERT_LT(sb.bilinear_mm, 1e-4);
    const Errors e = errors(r, ph);
    record("bezier_ideal", e);
    // RMSE ~0: samples within eps of an exactly representable curve.
    EXPECT_LT(r.rmse_um, 1e3 * sb.bilinear_mm);
    EXPECT_NEAR(r.cft_mm, ph.truth.cft_mm, sb.bilinear_mm + 1e-6);  // f32 depths: 2e-7 mm
    // Rim height: the best sample is within s/2 of the crest: T'' (s/2)^2 / 2 + eps.
    EXPECT_LT(e.rim_height, sb.bilinear_mm + 2.0 * 0.00585 * 0.00585 / 2);
    // Rim points: the crest of each half-line is found to within s/2 plus the argmax shift
    // sqrt(4 eps / |T''_rim|) that a perturbation eps can cause; diameters pair two of them.
    const double rim_pos = 0.00585 + std::sqrt(4.0 * sb.bilinear_mm / sb.rim_curv);
    EXPECT_LT(e.rim_diameter, 2.0 * rim_pos);
    // Rim area: the rim polygon's radii move by <= rim_pos: relative area change 2 rim_pos / r.
    EXPECT_LT(e.rim_area_rel, 2.0 * rim_pos / sb.min_rim_radius);
    // With the rim at most rim_pos off, the interior fit has P3 off by rim_pos: parameters that
    // scale with the rim radius (alpha, beta, slope point, pit flat) move by the same fraction
    // rim_pos / r_rim (< 1 %); the slope s ~ dy / w moves by that fraction of itself.
    const double frac = rim_pos / sb.min_rim_radius;
    EXPECT_LT(e.alpha, frac * 0.3 + 1e-4);
    EXPECT_LT(e.beta, frac * 0.6 + 1e-4);
    EXPECT_LT(e.slope_deg, frac * ph.truth.max_pit_slope_deg);
    EXPECT_LT(e.slope_diameter, frac * ph.truth.slope.diameter_mm + 2 * rim_pos);
    EXPECT_LT(e.flat_diameter, frac * ph.truth.pit_flat_diameter_mm + 1e-4);
    // Volumes: V_r integrates y r dr up to the rim: relative change <= 2 frac; V_IR stops at
    // r_u inside every rim and only feels the shape change (frac); V_p = A h - V_r is a small
    // difference of two terms each known to ~2 frac, so its bound scales by V_r / V_p (~14).
    EXPECT_LT(e.vr_rel, 2.0 * frac);
    EXPECT_LT(e.vir_rel, frac);
    EXPECT_LT(e.vp_rel, 4.0 * frac * ph.truth.rim_volume_mm3 / ph.truth.pit_volume_mm3);
    for (std::size_t i = 0; i < r.half_lines.size(); ++i) {
        EXPECT_NEAR(r.half_lines[i].angle_deg, ph.truth.half_lines[i].angle_deg, 1e-12);
        EXPECT_NEAR(r.half_lines[i].rim_radius_mm, ph.truth.half_lines[i].rim_radius_mm, rim_pos);
    }
    EXPECT_TRUE(r.qc_flags.empty());
}

// The real Iowa volume's sampling (tests/app/iowa_test.cpp): 19 B-scans 0.249 mm apart, 512
// A-scans 11.68 um apart, the same phantom eyes as at 61 B-scans. The bounds are those of the
// 61-B-scan test computed for this grid; the table (RecordProperty and stdout) shows what the
// coarse spacing costs each parameter (docs/algorithms/cube.md "Real eyes").
TEST(CubePhantom, NineteenBScansLikeTheRealIowaVolume) {
    for (const MaculaFamily f : {MaculaFamily::kBezier, MaculaFamily::kScheibe}) {
        MaculaPhantomParams p = volume_params(f, 19);
        p.size_x = 512;
        p.scale_x_mm = 0.011680;
        p.distance_mm = 0.249175;
        const MaculaPhantom ph = make_macula_phantom(p);
        const CubeResult r = analyse_macula(ph.scan);
        const Errors e = errors(r, ph);
        const MaculaPhantom dense = make_macula_phantom(volume_params(f, 61));
        const Errors e61 = errors(analyse_macula(dense.scan), dense);
        record(to_string(f) + "_19", e);
        std::printf("%-8s 19 B-scans: centre %.1f um, CFT %.2f um, rim height %.2f um, rim "
                    "diameter %.1f um, rim area %.2f %%, slope %.3f deg, Vr %.2f %%, Vp %.2f %%, "
                    "RMSE %.2f um | 61 B-scans: centre %.1f um, CFT %.2f um, rim diameter "
                    "%.1f um, rim area %.2f %%, Vr %.2f %%\n",
                    to_string(f).c_str(), 1e3 * e.centre, 1e3 * e.cft, 1e3 * e.rim_height,
                    1e3 * e.rim_diameter, 100 * e.rim_area_rel, e.slope_deg, 100 * e.vr_rel,
                    100 * e.vp_rel, e.rmse_um, 1e3 * e61.centre, 1e3 * e61.cft,
                    1e3 * e61.rim_diameter, 100 * e61.rim_area_rel, 100 * e61.vr_rel);
        if (f != MaculaFamily::kBezier) continue;  // the bounds are for the exact model
        const SamplingBounds sb = sampling_bounds(p, p.scale_x_mm, p.distance_mm,
                                                  CubeParams{}.tie_tolerance_mm);
        const double s2 = 0.5 * p.scale_x_mm;
        EXPECT_LE(e.centre, sb.centre_mm);
        EXPECT_LE(e.cft, sb.node_rise_mm + 0.0005 + sb.bilinear_mm);
        const double rim_pos = sb.centre_mm + s2 + std::sqrt(4 * sb.bilinear_mm / sb.rim_curv);
        EXPECT_LE(e.rim_diameter, 2.0 * rim_pos);
        EXPECT_LE(e.rim_area_rel, 2.0 * rim_pos / sb.min_rim_radius);
        EXPECT_LE(e.vr_rel, 2.0 * rim_pos / sb.min_rim_radius);
        EXPECT_LE(e.rmse_um, 1e3 * (sb.bilinear_mm + sb.node_rise_mm));
    }
}

// Errors of the full pipeline (centre searched) at 61, 97 and 193 B-scans.
std::array<Errors, 3> run_family(MaculaFamily f,
                                 bool flat,
                                 std::array<SamplingBounds, 3>* sb,
                                 std::array<MaculaPhantom, 3>* keep = nullptr) {
    std::array<Errors, 3> out;
    const std::array<int, 3> counts{61, 97, 193};
    for (std::size_t i = 0; i < 3; ++i) {
        const MaculaPhantomParams p = volume_params(f, counts[i], flat);
        MaculaPhantom ph = make_macula_phantom(p);
        const CubeResult r = analyse_macula(ph.scan);
        EXPECT_EQ(r.centre_source, "device thickness grid");
        EXPECT_TRUE(r.qc_flags.empty());
        out[i] = errors(r, ph);
        record(to_string(f) + (flat ? "_flat_" : "_") + std::to_string(counts[i]), out[i]);
        if (sb != nullptr) {
            (*sb)[i] = sampling_bounds(p, ph.scan.meta.scale_x_mm, ph.scan.meta.distance_mm,
                                       CubeParams{}.tie_tolerance_mm);
        }
        if (keep != nullptr) (*keep)[i] = std::move(ph);
    }
    return out;
}

// Slow: full-size phantom volumes (up to 401 x 768): seconds under the sanitizers.
SLOW_TEST(CubePhantom, BezierErrorsWithinSamplingBoundsAndShrinkWithBScans) {
    std::array<SamplingBounds, 3> sb;
    const auto e = run_family(MaculaFamily::kBezier, false, &sb);
    const double s2 = 0.5 * 0.01169;  // half a radial sample
    for (std::size_t i = 0; i < 3; ++i) {
        SCOPED_TRACE(i);
        // Centre within the bound argued in sampling_bounds().
        EXPECT_LE(e[i].centre, sb[i].centre_mm);
        // CFT is the value at the picked node (or of bilinear between tied nodes): it exceeds
        // the true minimum by at most delta + tie + eps.
        EXPECT_LE(e[i].cft, sb[i].node_rise_mm + 0.0005 + sb[i].bilinear_mm);
        // Rim height: the max along a ray from a centre e off sees the crest at an angle off by
        // <= e / (r_rim - e), i.e. |dh/dtheta| e / (r - e), plus eps and the discrete-sample
        // loss T'' s^2 / 8.
        EXPECT_LE(e[i].rim_height, sb[i].bilinear_mm +
                                       sb[i].rim_theta_slope * sb[i].centre_mm /
                                           (sb[i].min_rim_radius - sb[i].centre_mm) +
                                       2.0 * s2 * s2);
        // Rim diameter: each rim point moves by e (centre) + s/2 + sqrt(4 eps / |T''_rim|).
        const double rim_pos =
            sb[i].centre_mm + s2 + std::sqrt(4 * sb[i].bilinear_mm / sb[i].rim_curv);
        EXPECT_LE(e[i].rim_diameter, 2.0 * rim_pos);
        EXPECT_LE(e[i].rim_area_rel, 2.0 * rim_pos / sb[i].min_rim_radius);
        EXPECT_LE(e[i].vr_rel, 2.0 * rim_pos / sb[i].min_rim_radius);
        // Fit RMSE: the samples are within eps (+ the sample-to-centre mismatch) of a CuBe
        // curve; the fit cannot do worse than that curve.
        EXPECT_LE(e[i].rmse_um, 1e3 * (sb[i].bilinear_mm + sb[i].node_rise_mm));
    }
    // The error shrinks as the B-scans get denser (61 -> 97 -> 193). CFT depends only on the
    // picked node, which is the same row at 61 and 97 here (the fovea is 31 um off a row shared
    // by both grids): non-increasing, and strictly smaller at 193.
    EXPECT_LE(e[1].cft, e[0].cft + 1e-9);
    EXPECT_LT(e[2].cft, e[1].cft);
    for (auto get : {+[](const Errors& x) { return x.rim_diameter; },
                     +[](const Errors& x) { return x.rim_area_rel; },
                     +[](const Errors& x) { return x.vr_rel; },
                     +[](const Errors& x) { return x.slope_diameter; },
                     +[](const Errors& x) { return x.rmse_um; }}) {
        EXPECT_LT(get(e[1]), get(e[0]));
        EXPECT_LT(get(e[2]), get(e[1]));
    }
}

// Slow: full-size phantom volumes (up to 401 x 768): seconds under the sanitizers.
SLOW_TEST(CubePhantom, ScheibeWithinOnePercentAt193) {
    std::array<MaculaPhantom, 3> ph;
    const auto e = run_family(MaculaFamily::kScheibe, false, nullptr, &ph);
    const Errors& x = e[2];
    const MaculaTruth& t = ph[2].truth;
    // Targets (issue 3): 1 % (lengths: 2 um absolute where 1 % is smaller; slope 0.2 deg).
    auto tol = [](double v) { return std::max(0.01 * std::fabs(v), 0.002); };
    EXPECT_LE(x.cft, tol(t.cft_mm));
    EXPECT_LE(x.rim_height, tol(t.rim_height_mm));
    EXPECT_LE(x.rim_diameter, tol(t.rim.diameter_mm));
    EXPECT_LE(x.rim_area_rel, 0.01);
    EXPECT_LE(x.slope_diameter, tol(t.slope.diameter_mm));
    EXPECT_LE(x.slope_deg, 0.2);
    EXPECT_LE(x.vr_rel, 0.01);
    EXPECT_LE(x.vir_rel, 0.01);
    EXPECT_LE(x.vp_rel, 0.01);
    // Model limit (docs/algorithms/cube.md "Model limit"): a cubic cannot follow Scheibe's pit
    // bottom; the pit-flat diameter errs by 1-17 %. Assert that bound, and that the RMSE stays in
    // the model's 0.3-1.2 um band (plus the sampling of a 39 um grid, < 0.1 um here).
    EXPECT_LE(x.flat_diameter, 0.17 * t.pit_flat_diameter_mm);
    EXPECT_LE(x.rmse_um, 1.2);
}

// Slow: full-size phantom volumes (up to 401 x 768): seconds under the sanitizers.
SLOW_TEST(CubePhantom, ScheibeFlatPitsHitTheModelLimit) {
    // Flat Scheibe pits (gamma 3.2): the documented model limit. Measured from the true centre
    // so that sampling plays no part: what remains is the model's own error.
    // The model limit's statement is for the rim at the maximum sample (RimPoint::kMaximum,
    // docs/algorithms/cube.md step 4); the fitted rim (the default) carries the model mismatch into
    // the rim radius here: its errors are recorded, and reported in docs/algorithms/cube.md ("Rim
    // point").
    MaculaPhantomParams p = volume_params(MaculaFamily::kScheibe, 193, true);
    const MaculaPhantom ph = make_macula_phantom(p);
    CubeParams cp;
    cp.centre_mm = ph.centre_mm;
    record("scheibe_flat_true_centre_fitted_rim", errors(analyse_macula(ph.scan, cp), ph));
    cp.rim_point = RimPoint::kMaximum;
    const CubeResult r = analyse_macula(ph.scan, cp);
    const Errors e = errors(r, ph);
    record("scheibe_flat_true_centre", e);
    // Rim, CFT and volumes stay well under 1 % (the model limit).
    EXPECT_LE(e.rim_height, 0.01 * ph.truth.rim_height_mm);
    EXPECT_LE(e.rim_diameter, 0.01 * ph.truth.rim.diameter_mm);
    EXPECT_LE(e.vr_rel, 0.01);
    // Pit-flat diameter and maximum slope are where the cubic cannot follow Scheibe's pit
    // (the model limit); their errors here (recorded above, reported in docs/algorithms/cube.md)
    // exceed both the targets and the limit's indicative 17 % / 0.25 deg: no bound is
    // asserted for them rather than one fitted to the output.
}

TEST(CubeNoise, NodeNoiseEstimateRecoversThePhantomsNoise) {
    // thickness_noise_sd: MAD of the second differences along the A-scans / sqrt(6). The
    // phantom's thickness nodes carry independent N(0, sigma^2) (sigma / sqrt(2) on ILM and on
    // BM). Tolerance 4 %: 61 x 766 = 46,726 second differences; the MAD's relative SD is
    // 1.17 / sqrt(N) = 0.54 % for independent values, and neighbouring second differences share
    // nodes (correlation -2/3 at lag 1, 1/6 at lag 2), which at most triples the variance: SD
    // <= 1 %, so 4 % is 4 SDs. The surface's own second difference (|T''| dx^2 <= 0.06 um at
    // dx = 11.7 um) adds < 1e-4 relative to sigma sqrt(6) >= 4.9 um. A wrong constant (the
    // 1.4826 or the sqrt(6)) is off by 33 % or more.
    for (const double sigma_um : {2.0, 3.8717, 8.0}) {
        MaculaPhantomParams p;
        p.num_bscans = 61;
        p.pixels = false;
        p.noise_um = sigma_um / std::sqrt(2.0);
        p.seed = 11;
        const MaculaPhantom ph = make_macula_phantom(p);
        const double est_um = 1e3 * thickness_noise_sd(thickness_map(ph.scan));
        EXPECT_NEAR(est_um / sigma_um, 1.0, 0.04) << "sigma " << sigma_um << " um";
    }
    // Noise-free: only the surface's second differences remain (docs: ~0.0002 um).
    MaculaPhantomParams p;
    p.num_bscans = 61;
    p.pixels = false;
    EXPECT_LT(1e3 * thickness_noise_sd(thickness_map(make_macula_phantom(p).scan)), 0.06);
}

// Slow: full-size phantom volumes (up to 401 x 768): seconds under the sanitizers.
SLOW_TEST(CubePhantom, SegmentationNoiseGivesRmseOfTheNoiseLevel) {
    // 1 axial pixel of thickness noise: ILM and BM each carry sigma / sqrt(2) so that ILM - BM
    // has SD sigma = 3.87 um. A radial sample is a bilinear mix of 4 nodes with weights w:
    // its noise SD is sigma sqrt(sum w^2), sqrt(4/9) = 0.67 sigma on average over positions,
    // between 0.5 sigma and sigma; the fit absorbs little (~10 of ~170 degrees of freedom).
    // Three seeds: a bound that held for one lucky seed only proves nothing.
    const double sigma_um = 3.8717;
    for (const std::uint64_t seed : {7U, 8U, 9U}) {
        SCOPED_TRACE(seed);
        MaculaPhantomParams p = volume_params(MaculaFamily::kBezier, 193);
        p.noise_um = sigma_um / std::sqrt(2.0);
        p.seed = seed;
        const MaculaPhantom ph = make_macula_phantom(p);
        const CubeResult r = analyse_macula(ph.scan);
        const Errors e = errors(r, ph);
        record("bezier_noise_193_seed" + std::to_string(seed), e);
        EXPECT_GT(r.rmse_um, 0.5 * sigma_um);
        EXPECT_LT(r.rmse_um, 1.0 * sigma_um);
        // The 2 % target, for the parameters that are model estimates from many samples:
        // CFT (the shared P0.y of 24 interior fits, each over ~90 samples of SD ~2.6 um: its
        // random error ~2.6 / sqrt(24 * 90 / c) um with c ~ 10 for the correlation of samples
        // near the centre, ~0.2 um, plus the centre's offset; 2 % = 4.5 um), rim height (24
        // joint estimates of h_rim, each from the ~40 samples within 5 um of the crest: ~0.4 um
        // per line; 2 % = 7 um) and V_IR (integrates the interior up to 0.5 mm, averages 24
        // curves). The rim radius, and what scales with it (rim disk, V_r, V_p, beta, pit-flat,
        // slope disk, pit depth through the crest), misses 2 % at this noise: on a crest that
        // falls ~5 um over 0.2 mm the data do not fix the radius (docs/algorithms/cube.md,
        // "Accuracy"); those errors are recorded above, not asserted.
        const MaculaTruth& t = ph.truth;
        EXPECT_LE(e.cft, 0.02 * t.cft_mm);
        EXPECT_LE(e.rim_height, 0.02 * t.rim_height_mm);
        EXPECT_LE(e.vir_rel, 0.02);
        // The noise is far above CubeParams::local_fit_min_noise_um = 0.5 um: the CFT pass runs
        // on local fits and the final fit on sector bins, each over every node of its sector
        // (docs/algorithms/cube.md "Radial samples under noise"). The parameters that bilinear
        // samples left above 2 % but that average many samples meet it. Their errors over 36
        // seeds (7-42, docs/algorithms/cube.md "Accuracy", session 9), RMS / worst: pit depth
        // 0.51 / 1.19 %, max slope 0.47 / 1.05 %, V_p 0.52 / 1.21 %, rim diameter 0.65 / 1.46 %:
        // 2 % is >= 3.0 RMS (a 1-in-370 event for a normal error). Rim area and V_r (the rim
        // radius squared: 1.28 / 2.89 % and 1.39 / 3.17 %) meet it on these seeds at 1.6 and
        // 1.4 RMS (a seed misses with probability ~0.12 and ~0.15): asserted because the issue
        // asks for 2 %, and a regression of the rim radius fails them first.
        EXPECT_TRUE(r.noise_adaptive_samples);
        EXPECT_LE(std::fabs(r.pit_depth_mm / t.pit_depth_mm - 1.0), 0.02);
        EXPECT_LE(e.slope_deg, 0.02 * t.max_pit_slope_deg);
        EXPECT_LE(e.vp_rel, 0.02);
        EXPECT_LE(e.rim_diameter, 0.02 * t.rim.diameter_mm);
        EXPECT_LE(e.rim_area_rel, 0.02);
        EXPECT_LE(e.vr_rel, 0.02);
        // The rim at the maximum sample (the thesis's split) is pushed outward by the noise:
        // on a crest that falls ~5 um over 0.2 mm the largest of the ~40 samples within the
        // noise of the top is most often one of the outer ones, for every half-line alike, so
        // the bias survives the average over 24 half-lines (3-6 % of the diameter here). The
        // fitted rim has no such selection: its error must be well below that bias. Compared on
        // the bilinear samples of cube.md step 3, whose noise (0.5-1 sigma) the argument is about:
        // the local fits' smaller noise shrinks the maximum's bias itself.
        CubeParams crest_bilinear;
        crest_bilinear.local_fit_min_noise_um = std::numeric_limits<double>::infinity();
        const Errors c = errors(analyse_macula(ph.scan, crest_bilinear), ph);
        CubeParams at_max = crest_bilinear;
        at_max.rim_point = RimPoint::kMaximum;
        const Errors m = errors(analyse_macula(ph.scan, at_max), ph);
        record("bezier_noise_193_rim_at_maximum_seed" + std::to_string(seed), m);
        EXPECT_LT(c.rim_diameter, 0.5 * m.rim_diameter);
        EXPECT_LT(c.vr_rel, 0.5 * m.vr_rel);
    }
}

TEST(CubePhantom, AGivenCentreUnderNoiseIsAnalysedAsTheSearchedOne) {
    // A given centre (CubeParams::centre_mm, the validation path) must change the centre
    // alone: under noise it gets the same pit floor and CFT-pass centre sample as a searched
    // centre (docs/algorithms/cube.md "Centre"). Given exactly the searched centre, every
    // parameter is then the searched analysis's, to the last bit but for rounding in the
    // summation order (none: the same code runs on the same numbers). Before, a given centre
    // took the bilinear pit floor and centre sample (CFT +0.9 um biased at 61 B-scans, the
    // bias a true-centre oracle then misattributes to the centre).
    MaculaPhantomParams p = volume_params(MaculaFamily::kBezier, 61);
    p.noise_um = 3.8717;  // 1 axial pixel per surface
    p.seed = 2101;
    const MaculaPhantom ph = make_macula_phantom(p);
    const CubeResult searched = analyse_macula(ph.scan);
    ASSERT_TRUE(searched.noise_adaptive_samples);
    CubeParams cp;
    cp.centre_mm = searched.centre_mm;
    const CubeResult given = analyse_macula(ph.scan, cp);
    EXPECT_EQ(given.centre_source, "given");
    EXPECT_DOUBLE_EQ(given.cft_mm, searched.cft_mm);
    EXPECT_DOUBLE_EQ(given.pit_depth_mm, searched.pit_depth_mm);
    EXPECT_DOUBLE_EQ(given.alpha_mean_mm, searched.alpha_mean_mm);
    EXPECT_DOUBLE_EQ(given.pit_flat_diameter_mm, searched.pit_flat_diameter_mm);
    EXPECT_DOUBLE_EQ(given.rim.diameter_mm, searched.rim.diameter_mm);
    EXPECT_DOUBLE_EQ(given.inner_rim_volume_mm3, searched.inner_rim_volume_mm3);
    EXPECT_DOUBLE_EQ(given.pit_volume_mm3, searched.pit_volume_mm3);
}

TEST(CubePhantom, BiasUnderOnePixelOfNoiseIsWithinAThirdOfTheBound) {
    // Issue 32, item 5: |bias| <= 0.3 CRB at 1 axial pixel of segmentation noise on ILM and on
    // BM each (3.87 um; thickness node SD 5.48 um) on 61 B-scans. The CRB SDs below are the
    // Cramer-Rao bounds of the thesis's per-half-line model at this noise and sampling, centre
    // estimated (`macula_crb bias`, docs/algorithms/cube.md "Bias under noise at 61 B-scans"):
    // a property of the data, not of the analysis. The bias is estimated by the mean error of
    // 16 antithetic pairs (below) with its standard error SE measured from the pairs' scatter
    // (0.06-0.11 CRB here): an estimator whose bias is within 0.3 CRB passes
    // |mean| <= 0.3 CRB + 3 SE except with probability ~0.1 % per parameter, and the biases
    // this test guards against (the bilinear pit floor before: CFT +0.82, pit depth -0.88,
    // alpha_m +0.86, pit-flat diameter +0.90, slope diameter +0.87 CRB over 300 realisations)
    // exceed 0.3 + 3 SE. Seeds 2001..., not the bench's 1001...
    // V_IR (-0.39 CRB before the runs' nodes were moved along the profile, -0.17 after) is
    // asserted since then; the max slope (+0.38 CRB before its second-order noise term was
    // removed, +0.08 after) too; V_p (-1.50 CRB over the bench's 300 realisations before its
    // second-order noise term was removed, -0.23 after; here -0.00, SE 0.07, so the row, at
    // |mean| <= ~0.5 CRB, fails the code before: -1.35 CRB, SE 0.06). The RMS over the 32
    // analyses must stay within the 1.7 CRB (the bench: 0.82-1.17 CRB; V_p 1.79 before,
    // 1.03 after); an RMS over 32 draws is within +-25 % of its expectation at 2 SE.
    constexpr int kPairs = 16;
    struct Bound {
        const char* name;
        double crb;  // CRB SD (mm, mm2, mm3)
        double (*value)(const CubeResult&);
        double (*truth)(const MaculaTruth&);
    };
    const std::vector<Bound> bounds{
        {"cft", 1.113e-3, [](const CubeResult& r) { return r.cft_mm; },
         [](const MaculaTruth& t) { return t.cft_mm; }},
        {"rim_height", 0.3081e-3, [](const CubeResult& r) { return r.rim_height_mm; },
         [](const MaculaTruth& t) { return t.rim_height_mm; }},
        {"pit_depth", 1.095e-3, [](const CubeResult& r) { return r.pit_depth_mm; },
         [](const MaculaTruth& t) { return t.pit_depth_mm; }},
        {"rim_diameter", 24.36e-3, [](const CubeResult& r) { return r.rim.diameter_mm; },
         [](const MaculaTruth& t) { return t.rim.diameter_mm; }},
        {"rim_area", 0.08255, [](const CubeResult& r) { return r.rim.area_mm2; },
         [](const MaculaTruth& t) { return t.rim.area_mm2; }},
        {"max_slope", 0.1082, [](const CubeResult& r) { return r.max_pit_slope_deg; },  // deg
         [](const MaculaTruth& t) { return t.max_pit_slope_deg; }},
        {"slope_diameter", 19.28e-3, [](const CubeResult& r) { return r.slope.diameter_mm; },
         [](const MaculaTruth& t) { return t.slope.diameter_mm; }},
        {"slope_area", 0.0192, [](const CubeResult& r) { return r.slope.area_mm2; },
         [](const MaculaTruth& t) { return t.slope.area_mm2; }},
        {"flat_diameter", 9.106e-3, [](const CubeResult& r) { return r.pit_flat_diameter_mm; },
         [](const MaculaTruth& t) { return t.pit_flat_diameter_mm; }},
        {"flat_area", 0.00265, [](const CubeResult& r) { return r.pit_flat.area_mm2; },
         [](const MaculaTruth& t) { return t.pit_flat.area_mm2; }},
        {"rim_volume", 0.02914, [](const CubeResult& r) { return r.rim_volume_mm3; },
         [](const MaculaTruth& t) { return t.rim_volume_mm3; }},
        {"inner_rim_volume", 0.2371e-3,
         [](const CubeResult& r) { return r.inner_rim_volume_mm3; },
         [](const MaculaTruth& t) { return t.inner_rim_volume_mm3; }},
        {"pit_volume", 1.804e-3, [](const CubeResult& r) { return r.pit_volume_mm3; },
         [](const MaculaTruth& t) { return t.pit_volume_mm3; }},
        {"alpha_mean", 15.85e-3, [](const CubeResult& r) { return r.alpha_mean_mm; },
         [](const MaculaTruth& t) { return *t.alpha_mean_mm; }},
        {"beta_mean", 23.36e-3, [](const CubeResult& r) { return r.beta_mean_mm; },
         [](const MaculaTruth& t) { return *t.beta_mean_mm; }},
    };
    // Antithetic pairs: each noisy scan and its mirror 2 clean - noisy (the same noise with the
    // opposite sign, as likely under the phantom's Gaussian noise). The pair's mean error has
    // the bias as its expectation, exactly, but not the error's first-order (odd) part, which
    // is most of its variance: their SE is 2-3x below that of 32 independent draws.
    const MaculaPhantomParams clean_params = volume_params(MaculaFamily::kBezier, 61);
    const MaculaPhantom clean = make_macula_phantom(clean_params);
    std::vector<std::vector<double>> err(bounds.size());  // pair means
    std::vector<std::vector<double>> single(bounds.size());
    for (int s = 0; s < kPairs; ++s) {
        MaculaPhantomParams p = clean_params;
        p.noise_um = 3.8717;
        p.seed = static_cast<std::uint64_t>(2001 + s);
        const MaculaPhantom ph = make_macula_phantom(p);
        io::Scan mirror = ph.scan;
        for (std::size_t b = 0; b < mirror.bscans.size(); ++b) {
            auto& seg = mirror.bscans[b].seg;
            for (std::size_t k = 0; k < seg.size(); ++k) {
                for (std::size_t a = 0; a < seg[k].size(); ++a) {
                    seg[k][a] = 2.0F * clean.scan.bscans[b].seg[k][a] - seg[k][a];
                }
            }
        }
        const CubeResult r = analyse_macula(ph.scan);
        const CubeResult m = analyse_macula(mirror);
        for (std::size_t k = 0; k < bounds.size(); ++k) {
            const double truth = bounds[k].truth(ph.truth);
            const double e = bounds[k].value(r) - truth;
            const double f = bounds[k].value(m) - truth;
            // A disk is omitted (NaN) when a half-line fails: the pair is then left out.
            if (std::isfinite(e) && std::isfinite(f)) err[k].push_back(0.5 * (e + f));
            for (const double x : {e, f}) {
                if (std::isfinite(x)) single[k].push_back(x);
            }
        }
    }
    for (std::size_t k = 0; k < bounds.size(); ++k) {
        SCOPED_TRACE(bounds[k].name);
        const std::vector<double>& e = err[k];
        ASSERT_GE(e.size(), static_cast<std::size_t>(kPairs - 2));
        const auto n = static_cast<double>(e.size());
        double mean = 0.0;
        for (const double x : e) mean += x / n;
        double var = 0.0;
        for (const double x : e) var += (x - mean) * (x - mean) / (n - 1.0);
        const double se = std::sqrt(var / n);
        EXPECT_LE(std::fabs(mean), 0.3 * bounds[k].crb + 3.0 * se)
            << "bias " << mean / bounds[k].crb << " CRB, SE " << se / bounds[k].crb << " CRB";
        double ms = 0.0;
        for (const double x : single[k]) ms += x * x / static_cast<double>(single[k].size());
        EXPECT_LE(std::sqrt(ms), 1.7 * bounds[k].crb) << "RMS " << std::sqrt(ms) / bounds[k].crb;
    }
}

TEST(CubePhantom, NoiseAdaptiveSamplesOfANoiseFreeMapStayWithinTheSamplingBounds) {
    // The noise-adaptive samples forced on (threshold 0) on the noise-free Bezier phantoms. The
    // local fits of the CFT pass, quadratic in the radius and linear across, reproduce a
    // rotationally symmetric map up to its quartic radial terms; the sector bins of the final
    // fit are means of nodes each moved along the CFT pass's fitted profile T^ to the run's
    // mean radius, so a run's mean errs only by |T'' - T^''| var(r) / 2 (< 1e-4 um where a run
    // spans a few um; near the centre T^ carries the pit floor's curvature). So both must stay
    // within
    // the sampling bounds that the bilinear samples are held to
    // (BezierErrorsWithinSamplingBoundsAndShrinkWithBScans). By default (threshold 0.5 um)
    // these maps keep their bilinear samples.
    const double s2 = 0.5 * 0.01169;
    for (const int nb : {61, 193}) {
        SCOPED_TRACE(nb);
        const MaculaPhantomParams p = volume_params(MaculaFamily::kBezier, nb);
        const MaculaPhantom ph = make_macula_phantom(p);
        EXPECT_FALSE(analyse_macula(ph.scan).noise_adaptive_samples);
        CubeParams forced;
        forced.local_fit_min_noise_um = 0.0;
        const CubeResult r = analyse_macula(ph.scan, forced);
        EXPECT_TRUE(r.noise_adaptive_samples);
        const Errors e = errors(r, ph);
        record("bezier_noise_adaptive_" + std::to_string(nb), e);
        const SamplingBounds sb = sampling_bounds(p, ph.scan.meta.scale_x_mm,
                                                  ph.scan.meta.distance_mm,
                                                  CubeParams{}.tie_tolerance_mm);
        EXPECT_LE(e.centre, sb.centre_mm);
        EXPECT_LE(e.cft, sb.node_rise_mm + 0.0005 + sb.bilinear_mm);
        const double rim_pos = sb.centre_mm + s2 + std::sqrt(4 * sb.bilinear_mm / sb.rim_curv);
        EXPECT_LE(e.rim_diameter, 2.0 * rim_pos);
        EXPECT_LE(e.rim_area_rel, 2.0 * rim_pos / sb.min_rim_radius);
        EXPECT_LE(e.vr_rel, 2.0 * rim_pos / sb.min_rim_radius);
        // The RMSE is measured against the bilinear samples either way.
        EXPECT_LE(e.rmse_um, 1e3 * (sb.bilinear_mm + sb.node_rise_mm));
    }
}

TEST(CubePhantom, OsGivesTheParametersOfItsMirroredOdTwin) {
    // The OS twin is the OD volume mirrored in x (fovea and grid hint offsets mirrored); its
    // thickness map equals the mirrored OD map to f32 rounding (1e-6 mm), so every parameter and
    // every anatomical half-line must agree to that rounding.
    MaculaPhantomParams od = volume_params(MaculaFamily::kBezier, 61);
    od.grid_hint_dx_mm = 0.0;
    od.grid_hint_dy_mm = 0.0;
    MaculaPhantomParams os = od;
    os.eye = io::Laterality::kOS;
    os.fovea_dx_mm = -od.fovea_dx_mm;
    const CubeResult a = analyse_macula(make_macula_phantom(od).scan);
    const CubeResult b = analyse_macula(make_macula_phantom(os).scan);
    const double tol = 1e-5;
    EXPECT_NEAR(a.cft_mm, b.cft_mm, tol);
    EXPECT_NEAR(a.rim_height_mm, b.rim_height_mm, tol);
    EXPECT_NEAR(a.rim.diameter_mm, b.rim.diameter_mm, tol);
    EXPECT_NEAR(a.rim.area_mm2, b.rim.area_mm2, tol);
    EXPECT_NEAR(a.max_pit_slope_deg, b.max_pit_slope_deg, 1e-3);
    EXPECT_NEAR(a.rim_volume_mm3, b.rim_volume_mm3, tol);
    EXPECT_NEAR(a.pit_volume_mm3, b.pit_volume_mm3, tol);
    // Normals in the grid frame mirror in x.
    EXPECT_NEAR(a.rim.normal[0], -b.rim.normal[0], 1e-4);
    EXPECT_NEAR(a.rim.normal[1], b.rim.normal[1], 1e-4);
    ASSERT_EQ(a.half_lines.size(), b.half_lines.size());
    for (std::size_t i = 0; i < a.half_lines.size(); ++i) {
        EXPECT_NEAR(a.half_lines[i].rim_radius_mm, b.half_lines[i].rim_radius_mm, tol);
        EXPECT_NEAR(a.half_lines[i].rim_height_mm, b.half_lines[i].rim_height_mm, tol);
        EXPECT_NEAR(a.half_lines[i].direction.x(), -b.half_lines[i].direction.x(), 1e-12);
        EXPECT_NEAR(a.half_lines[i].direction.y(), b.half_lines[i].direction.y(), 1e-12);
    }
    // Anatomy: OD half-line 0 (nasal) points along grid +x, OS along grid -x.
    EXPECT_GT(a.half_lines[0].direction.x(), 0.99);
    EXPECT_LT(b.half_lines[0].direction.x(), -0.99);
    EXPECT_GT(a.half_lines[6].direction.y(), 0.99);  // 90 deg superior = grid +y
}

TEST(CubeLine, PhantomLineScanGivesTheTwoDimensionalParameters) {
    // The bundled line phantom (768 A-scans, ScaleX 11.69 um, fovea 30 um off the scan centre,
    // i.e. off every node by 0.4 samples). The centre node is within 5.9 um of the true centre:
    // CFT rises by < dy (r/3a)^2 ~ 0.1 um; rims are found within s/2 + e = 12 um; the slope
    // changes by that fraction of the rim radius (1 %) at most.
    const io::Scan scan =
        io::read_scan((test::source_dir() / "sample_scans/macula_line_od.vol").string());
    MaculaPhantomParams p;
    p.line = true;
    p.fovea_dx_mm = 0.03;
    const MaculaTruth t = macula_truth(p);
    const CubeResult r = analyse_macula(scan);
    EXPECT_TRUE(r.line_scan);
    ASSERT_EQ(r.half_lines.size(), 2U);
    EXPECT_NEAR(r.cft_mm, t.cft_mm, 0.0005);
    EXPECT_NEAR(r.rim_height_mm, t.rim_height_mm, 0.0005);
    for (std::size_t i = 0; i < 2; ++i) {
        EXPECT_EQ(r.half_lines[i].angle_deg, t.half_lines[i].angle_deg);
        EXPECT_NEAR(r.half_lines[i].rim_radius_mm, t.half_lines[i].rim_radius_mm, 0.012);
        EXPECT_NEAR(r.half_lines[i].max_slope_deg, t.half_lines[i].max_slope_deg,
                    0.01 * t.half_lines[i].max_slope_deg);
    }
    EXPECT_LT(r.rmse_um, 0.5);  // exactly representable, 1-D interpolation only
    EXPECT_TRUE(std::isnan(r.rim_volume_mm3));
    EXPECT_TRUE(std::isnan(r.rim.area_mm2));
    EXPECT_FALSE(r.notes.empty());
}

TEST(CubeLine, RealFovealLineScanIsPhysiological) {
    SKIP_UNLESS_SHARED("realdata/fovea_line_716_0.vol");
    const io::Scan scan = io::read_scan(test::realdata("fovea_line_716_0.vol").string());
    const CubeResult r = analyse_macula(scan);
    ASSERT_TRUE(r.line_scan);
    // Anatomical ranges (thesis Table 7.3: CFT 0.19-0.27 mm, rim 0.29-0.39 mm).
    EXPECT_GE(r.cft_mm, 0.15);
    EXPECT_LE(r.cft_mm, 0.35);
    for (const auto& h : r.half_lines) {
        ASSERT_TRUE(h.valid) << h.problem;
        EXPECT_GE(h.rim_height_mm, 0.25);
        EXPECT_LE(h.rim_height_mm, 0.45);
        EXPECT_GE(h.rim_radius_mm, 0.5);
        EXPECT_LE(h.rim_radius_mm, 2.0);
        EXPECT_GT(h.max_slope_deg, 3.0);
        EXPECT_LT(h.max_slope_deg, 25.0);
    }
    // Thesis: 1.0-7.1 um on real scans.
    EXPECT_LT(r.rmse_um, 7.1);
    RecordProperty("real_line", "cft " + std::to_string(r.cft_mm) + " rim " +
                                    std::to_string(r.half_lines[0].rim_height_mm) + "/" +
                                    std::to_string(r.half_lines[1].rim_height_mm) + " rmse " +
                                    std::to_string(r.rmse_um));
}

TEST(CubeBadInput, CircleScanAndMissingBmAreRefused) {
    MaculaPhantomParams p = volume_params(MaculaFamily::kBezier, 61);
    MaculaPhantom ph = make_macula_phantom(p);
    io::Scan circle = ph.scan;
    circle.meta.pattern = io::ScanPattern::kCircle;
    try {
        (void)analyse_macula(circle);
        FAIL();
    } catch (const AnalysisError& e) {
        EXPECT_NE(std::string(e.what()).find("circle"), std::string::npos) << e.what();
    }
    io::Scan no_bm = ph.scan;
    for (auto& b : no_bm.bscans) {
        std::fill(b.seg[1].begin(), b.seg[1].end(), std::numeric_limits<float>::quiet_NaN());
    }
    try {
        (void)analyse_macula(no_bm);
        FAIL();
    } catch (const AnalysisError& e) {
        EXPECT_NE(std::string(e.what()).find("BM"), std::string::npos) << e.what();
    }
}

TEST(CubePhantom, MissingValuesInThePitAreFlagged) {
    MaculaPhantomParams p = volume_params(MaculaFamily::kBezier, 61);
    MaculaPhantom ph = make_macula_phantom(p);
    // Remove a few A-scans next to the fovea on its B-scan.
    const int b = static_cast<int>(std::lround(ph.centre_mm.y() / ph.scan.meta.distance_mm));
    const int a = static_cast<int>(std::lround(ph.centre_mm.x() / ph.scan.meta.scale_x_mm));
    for (int k = a + 10; k < a + 14; ++k) {
        ph.scan.bscans[static_cast<std::size_t>(b)].seg[0][static_cast<std::size_t>(k)] =
            std::numeric_limits<float>::quiet_NaN();
    }
    const CubeResult r = analyse_macula(ph.scan);
    EXPECT_NE(std::find(r.qc_flags.begin(), r.qc_flags.end(), "missing values in the pit"),
              r.qc_flags.end());
}

}  // namespace
}  // namespace octshape::retina
