#include "octshape/retina/phantom_onh.h"

#include <cmath>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <sstream>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "octshape/error.h"
#include "octshape/io/vol.h"
#include "octshape/version.h"
#include "test_paths.h"

namespace octshape::retina {
namespace {

constexpr double kPi = std::numbers::pi;

// Truth options that keep a test fast; the quadratures are still converged (see Convergence).
OnhTruthOptions fast_options() {
    OnhTruthOptions o;
    o.s_step = 0.01;  // the overhang's steep wall needs it (see CoarseStepsConvergeFast)
    o.phi_steps = 64;
    o.mrw_points = 24;
    o.mrw_search_step = 0.01;
    return o;
}

OnhPhantomParams small(OnhShape shape, int bscans = 25, int ascans = 64) {
    OnhPhantomParams p = onh_phantom_preset(shape);
    p.num_bscans = bscans;
    p.num_ascans = ascans;
    return p;
}

OnhProfileParams flat_profile(double thickness_mm) {
    OnhProfileParams pr;
    pr.retina_thickness_mm = thickness_mm;
    pr.rim_height_mm = 0.0;
    pr.swelling_mm = 0.0;
    pr.cup_depth_mm = 0.0;
    pr.undercut = 0.0;
    return pr;
}

// BMO centre in grid mm, from the documented layout (independent of the generator's code).
Eigen::Vector2d expected_centre(const OnhPhantomParams& p) {
    const double width = (p.num_ascans - 1) * p.field_mm / p.num_ascans;
    return {width / 2 + p.bmo_offset_x_mm, p.field_mm / 2 + p.bmo_offset_y_mm};
}

// True when grid (x, y) lies inside the BMO ellipse (from the ellipse equation).
bool inside_ellipse(const OnhPhantomParams& p, double x, double y) {
    const Eigen::Vector2d d = Eigen::Vector2d(x, y) - expected_centre(p);
    const double t = p.bmo_rotation_deg * kPi / 180.0;
    const double u = std::cos(t) * d.x() + std::sin(t) * d.y();
    const double v = -std::sin(t) * d.x() + std::cos(t) * d.y();
    return (u / p.bmo_semi_major_mm) * (u / p.bmo_semi_major_mm) +
               (v / p.bmo_semi_minor_mm) * (v / p.bmo_semi_minor_mm) <
           1.0;
}

double display(float v) { return std::pow(static_cast<double>(v), 0.25); }

// ---------------------------------------------------------------------------------------------
// Truth against closed forms

// A flat ILM at constant height T above the RPE: every volume is T times its area, whatever
// the BM curvature (h and the projected area do not depend on it). The integrands are
// polynomials in s (exact for Gauss-Legendre) and smooth periodic functions in phi (trapezoid
// converges geometrically), so only rounding remains: 1e-10 relative is ample.
TEST(OnhTruth, FlatIlmVolumesAreHeightTimesArea) {
    OnhPhantomParams p = small(OnhShape::kCupped);
    p.profile = flat_profile(0.25);
    OnhTruthOptions o = fast_options();
    const OnhTruth t = compute_onh_truth(p, o);
    const double a = p.bmo_semi_major_mm;
    const double b = p.bmo_semi_minor_mm;
    const double tol = 1e-10;
    EXPECT_NEAR(t.bmo_area_mm2, kPi * a * b, 1e-15);
    EXPECT_NEAR(t.bmo_volume_mm3, 0.25 * kPi * a * b, tol);
    EXPECT_NEAR(t.total_volume_mm3, 0.25 * kPi * 1.5 * 1.5, tol);
    EXPECT_NEAR(t.annular_volume_mm3, 0.25 * (kPi * 1.5 * 1.5 - kPi * a * b), tol);
    EXPECT_EQ(t.cup_volume_mm3, 0.0);
    EXPECT_FALSE(t.has_cup);
    EXPECT_NEAR(t.conht_mm, 0.25, 1e-15);
    EXPECT_NEAR(t.bmo_centre_mm[0], expected_centre(p).x(), 1e-12);
    EXPECT_NEAR(t.bmo_centre_mm[1], expected_centre(p).y(), 1e-12);
}

// On a flat tilted BM the ILM is the parallel plane T above it: the MRW is the plane distance
// T / sqrt(1 + tx^2 + ty^2), each MRW quad is a rectangle of width |p_i+1 - p_i| and height
// that distance, and every normal is the same (bending energy 0).
TEST(OnhTruth, FlatTiltedPlaneMrwAreaAndBendingEnergy) {
    OnhPhantomParams p = small(OnhShape::kCupped);
    p.profile = flat_profile(0.25);
    p.eye_radius_mm = 0.0;
    p.tilt_x = 0.05;
    p.tilt_y = -0.03;
    const OnhTruth t = compute_onh_truth(p, fast_options());
    const double d = 0.25 / std::sqrt(1.0 + 0.05 * 0.05 + 0.03 * 0.03);
    ASSERT_EQ(t.mrw_mm.size(), 24U);
    // Closest-point search converges to 1e-14 in the parameters; the distance is quadratic in
    // the parameter error at the minimum, so 1e-10 mm is far above what remains.
    for (double m : t.mrw_mm) EXPECT_NEAR(m, d, 1e-10);
    EXPECT_NEAR(t.mrw_mean_mm, d, 1e-10);
    // Ellipse points from the ellipse formula, on the BM plane.
    const Eigen::Vector2d c = expected_centre(p);
    const double th = p.bmo_rotation_deg * kPi / 180.0;
    double perimeter = 0.0;
    std::vector<Eigen::Vector3d> pts;
    for (int i = 0; i < 24; ++i) {
        const double s = 2.0 * kPi * i / 24;
        const double u = p.bmo_semi_major_mm * std::cos(s);
        const double v = p.bmo_semi_minor_mm * std::sin(s);
        const Eigen::Vector2d xy = c + Eigen::Vector2d(std::cos(th) * u - std::sin(th) * v,
                                                       std::sin(th) * u + std::cos(th) * v);
        pts.emplace_back(xy.x(), xy.y(), 0.05 * (xy.x() - c.x()) - 0.03 * (xy.y() - c.y()));
    }
    for (int i = 0; i < 24; ++i) {
        const auto ii = static_cast<std::size_t>(i);
        EXPECT_NEAR(t.bmo_points_mm[ii].x(), pts[ii].x(), 1e-12);
        EXPECT_NEAR(t.bmo_points_mm[ii].y(), pts[ii].y(), 1e-12);
        // z is relative to the BM at the centre, which sits at an arbitrary depth.
        EXPECT_NEAR(t.bmo_points_mm[ii].z() - t.rpe_centre_height_mm, pts[ii].z(), 1e-12);
        perimeter += (pts[static_cast<std::size_t>((i + 1) % 24)] - pts[ii]).norm();
    }
    // Quad corners sit on the exact MRW points (1e-8 mm in position: the distance is flat at
    // the minimum, so positions are known to ~sqrt(1e-16)).
    EXPECT_NEAR(t.mrw_area_mm2, d * perimeter, 1e-6);
    EXPECT_NEAR(t.bending_energy, 0.0, 1e-12);
}

// A spherical-cap cup (circular BMO): the cup is the spherical segment of height D - T below
// the RPE, V = pi h^2 (3 R - h) / 3; the whole dent below the plane at T is the segment of
// height D. The integrand is smooth between the break points (cup edge, h = 0); 1e-9.
TEST(OnhTruth, SphericalCapCupVolumeIsTheSphericalSegment) {
    OnhPhantomParams p = small(OnhShape::kCupped);
    p.bmo_semi_major_mm = p.bmo_semi_minor_mm = 0.8;
    p.profile = flat_profile(0.3);
    p.profile.cup_profile = CupProfile::kSpherical;
    p.profile.cup_depth_mm = 0.5;
    p.profile.cup_radius = 0.7;
    const OnhTruth t = compute_onh_truth(p, fast_options());
    const double a = 0.8;
    const double rc = 0.7 * a;
    const double radius = (rc * rc + 0.25) / (2.0 * 0.5);
    auto segment = [&](double h) { return kPi * h * h * (3.0 * radius - h) / 3.0; };
    const double cup = segment(0.5 - 0.3);
    const double dent = segment(0.5);
    EXPECT_NEAR(t.cup_volume_mm3, cup, 1e-9);
    EXPECT_TRUE(t.has_cup);
    EXPECT_NEAR(t.bmo_volume_mm3, 0.3 * kPi * a * a - dent + cup, 1e-9);
    EXPECT_NEAR(t.total_volume_mm3, 0.3 * kPi * 1.5 * 1.5 - dent + cup, 1e-9);
    EXPECT_NEAR(t.annular_volume_mm3, 0.3 * kPi * (1.5 * 1.5 - a * a), 1e-9);
    EXPECT_NEAR(t.conht_mm, 0.3 - 0.5, 1e-15);
}

// Bending energy of a spherical cap of half-angle alpha (flat BM, BMO region entirely on the
// sphere): the normal tensor has lambda_z = (1 - cos^3 alpha) / (3 (1 - cos alpha)) and
// E_b = 1 - lambda_z.
TEST(OnhTruth, SphericalCapBendingEnergyHasItsClosedForm) {
    OnhPhantomParams p = small(OnhShape::kCupped);
    p.bmo_semi_major_mm = p.bmo_semi_minor_mm = 0.8;
    p.eye_radius_mm = 0.0;
    p.tilt_x = p.tilt_y = 0.0;
    p.profile = flat_profile(0.3);
    p.profile.cup_profile = CupProfile::kSpherical;
    p.profile.cup_depth_mm = 0.25;
    p.profile.cup_radius = 1.2;
    const OnhTruth t = compute_onh_truth(p, fast_options());
    const double rc = 1.2 * 0.8;
    const double radius = (rc * rc + 0.25 * 0.25) / (2.0 * 0.25);
    const double ca = std::cos(std::asin(0.8 / radius));
    const double lz = (1.0 - ca * ca * ca) / (3.0 * (1.0 - ca));
    EXPECT_NEAR(t.bending_energy, 1.0 - lz, 1e-9);
}

// The swollen preset on a circular BMO: h >= 0 everywhere and every volume is
// 2 pi a^2 I(R) with I(R) = integral_0^R f(s) s ds in closed form (the rim term integrates to
// H r^2 e (1 - (1 + V) e^-V) / 2 with V = R^2 / r^2, the Gaussian to P sigma^2 (1 - e^(-R^2 /
// 2 sigma^2)), the (1 - s^2/rc^2)^3 dip to D rc^2 / 8).
TEST(OnhTruth, SwollenDiscVolumesHaveTheirClosedForm) {
    OnhPhantomParams p = small(OnhShape::kSwollen);
    const double a = 0.85;
    p.bmo_semi_major_mm = p.bmo_semi_minor_mm = a;
    const OnhProfileParams& f = p.profile;
    ASSERT_EQ(f.cup_exponent, 2);
    auto integral = [&](double r) {
        const double rr = f.rim_radius * f.rim_radius;
        const double v = r * r / rr;
        const double ss = f.swelling_width * f.swelling_width;
        return f.retina_thickness_mm * r * r / 2.0 +
               f.rim_height_mm * rr * std::exp(1.0) * (1.0 - (1.0 + v) * std::exp(-v)) / 2.0 +
               f.swelling_mm * ss * (1.0 - std::exp(-r * r / (2.0 * ss))) -
               f.cup_depth_mm * f.cup_radius * f.cup_radius / 8.0;
    };
    const OnhTruth t = compute_onh_truth(p, fast_options());
    const double bmo = 2.0 * kPi * a * a * integral(1.0);
    const double total = 2.0 * kPi * a * a * integral(1.5 / a);
    EXPECT_NEAR(t.bmo_volume_mm3, bmo, 1e-9);
    EXPECT_NEAR(t.total_volume_mm3, total, 1e-9);
    EXPECT_NEAR(t.annular_volume_mm3, total - bmo, 1e-9);
    EXPECT_EQ(t.cup_volume_mm3, 0.0);
    EXPECT_NEAR(t.conht_mm, f.retina_thickness_mm + f.swelling_mm - f.cup_depth_mm, 1e-15);
}

// Every value computed twice (all steps halved the second time) changes by less than its
// bound: Gauss-Legendre-8 on analytic pieces between exact break points and a periodic
// trapezoid rule leave errors near rounding (1e-12 relative); a missed break point would
// leave O(step^2) ~ 1e-4. MRW points are located to ~1e-8 mm (flat minimum), which moves
// the quad areas by ~1e-8 mm^2 per point.
TEST(OnhTruth, QuadraturesConvergeOnEveryPreset) {
    for (OnhShape shape : {OnhShape::kCupped, OnhShape::kSwollen, OnhShape::kOverhang}) {
        const OnhTruth t = compute_onh_truth(small(shape), fast_options());
        ASSERT_GE(t.accuracy.size(), 9U);
        for (const TruthAccuracy& a : t.accuracy) {
            const double bound = a.name == "mrw_area_mm2" ? 1e-6 : 1e-10;
            EXPECT_LE(a.abs_change, bound) << to_string(shape) << " " << a.name;
            EXPECT_FALSE(a.method.empty()) << a.name;
        }
    }
}

// The rules converge at high order instead of sitting on one resolution: on the overhang
// (steepest wall, so the slowest case) the change of the bending energy from step h to h/2
// shrinks by far more than 2^4 from h = 0.04 to h = 0.02 (Gauss-Legendre-8 is of order 16 on
// smooth pieces; a missed break point, i.e. a kink inside a piece, would give order ~2).
TEST(OnhTruth, CoarseStepsConvergeFast) {
    const OnhPhantomParams p = small(OnhShape::kOverhang);
    OnhTruthOptions o = fast_options();
    o.mrw_points = 8;
    o.s_step = 0.04;
    const OnhTruth a = compute_onh_truth(p, o);  // steps 0.04 and 0.02
    o.s_step = 0.01;
    const OnhTruth b = compute_onh_truth(p, o);  // steps 0.01 and 0.005
    auto entry = [](const OnhTruth& t, const std::string& name) {
        for (const TruthAccuracy& x : t.accuracy) {
            if (x.name == name) return x;
        }
        return TruthAccuracy{};
    };
    const TruthAccuracy ea = entry(a, "bending_energy");
    const TruthAccuracy eb = entry(b, "bending_energy");
    const double d1 = std::fabs(ea.value_coarse - ea.value);  // 0.04 -> 0.02
    const double d2 = std::fabs(ea.value - eb.value_coarse);  // 0.02 -> 0.01
    EXPECT_GT(d1, 0.0);
    EXPECT_GT(d1, 16.0 * d2);
    EXPECT_LT(std::fabs(eb.value - eb.value_coarse), 1e-10);
}

// Total = BMO region + annulus when the ellipse lies inside the disc (a consistency check of
// the phi quadrature against the phi-free BMO integral).
TEST(OnhTruth, TotalIsBmoPlusAnnulus) {
    for (OnhShape shape : {OnhShape::kCupped, OnhShape::kSwollen, OnhShape::kOverhang}) {
        const OnhTruth t = compute_onh_truth(small(shape), fast_options());
        EXPECT_NEAR(t.total_volume_mm3, t.bmo_volume_mm3 + t.annular_volume_mm3, 1e-10)
            << to_string(shape);
        EXPECT_GT(t.bmo_volume_mm3, 0.0);
    }
}

// MRW points are true closest points: the offset is normal to the surface at the MRW point
// (first-order optimality), and a dense sampling of the surface finds nothing closer. The
// sampling is uniform in arc length (<= 1 um along the meridian, <= 1.5 um around), so every
// surface point is within 0.9 um of a sample and the sampled minimum exceeds the true one by
// less than 1e-3 mm; it can never be below it.
TEST(OnhTruth, MrwPointsAreClosestPointsOnTheOverhang) {
    const OnhPhantomParams p = small(OnhShape::kOverhang);
    OnhTruthOptions o = fast_options();
    o.mrw_points = 8;
    const OnhTruth t = compute_onh_truth(p, o);
    const OnhPhantomGeometry g(p);
    for (std::size_t i = 0; i < t.mrw_mm.size(); i += 2) {
        const Eigen::Vector3d& bmo = t.bmo_points_mm[i];
        const double ti = 2.0 * kPi * static_cast<double>(i) / 8.0;
        // Only points whose normalised position is within 0.25 of the BMO point's can be closer
        // than 0.18 mm (0.25 normalised >= 0.25 b = 0.19 mm in the plane), so the sampling
        // covers |phi - t| <= 0.25 and |rho - 1| <= 0.25.
        ASSERT_LT(t.mrw_mm[i], 0.18);
        double best = std::numeric_limits<double>::infinity();
        for (double phi = ti - 0.25; phi <= ti + 0.25; phi += 0.001) {
            double s = 0.0;
            while (s < 1.6) {
                const double speed = g.surface_ds(s, phi).norm();
                if (std::fabs(g.rho(s) - 1.0) <= 0.25) {
                    best = std::min(best, (g.surface(s, phi) - bmo).norm());
                }
                s += 1e-3 / std::max(speed, 1e-3);
            }
        }
        EXPECT_GE(best, t.mrw_mm[i] - 1e-12) << i;
        EXPECT_LE(best, t.mrw_mm[i] + 1e-3) << i;
        const Eigen::Vector3d q = t.mrw_points_mm[i];
        EXPECT_NEAR((q - bmo).norm(), t.mrw_mm[i], 1e-15);
    }
}

// First-order optimality at every MRW point of every preset: q - p is orthogonal to both
// tangents X_s, X_phi at q (relative 1e-6: the parameters are located to ~1e-8).
TEST(OnhTruth, MrwOffsetsAreNormalToTheIlm) {
    for (OnhShape shape : {OnhShape::kCupped, OnhShape::kSwollen, OnhShape::kOverhang}) {
        const OnhPhantomParams p = small(shape);
        const OnhTruth t = compute_onh_truth(p, fast_options());
        const OnhPhantomGeometry g(p);
        for (std::size_t i = 0; i < t.mrw_mm.size(); ++i) {
            const Eigen::Vector3d q = t.mrw_points_mm[i];
            // Recover (s, phi) of q: phi from the normalised frame, s from rho(s) = |v| on the
            // crossing at q's height.
            const Eigen::Vector2d v = g.normalised(q.x(), q.y());
            const double phi = std::atan2(v.y(), v.x());
            double s_best = -1.0;
            for (double s : g.rho_roots(v.norm())) {
                if (s_best < 0.0 || std::fabs(g.surface(s, phi).z() - q.z()) <
                                        std::fabs(g.surface(s_best, phi).z() - q.z())) {
                    s_best = s;
                }
            }
            ASSERT_GE(s_best, 0.0);
            const Eigen::Vector3d d = (q - t.bmo_points_mm[i]).normalized();
            const Eigen::Vector3d xs = g.surface_ds(s_best, phi);
            const Eigen::Vector3d xp = g.surface_dphi(s_best, phi);
            EXPECT_LT(std::fabs(d.dot(xs)) / xs.norm(), 1e-6) << to_string(shape) << " " << i;
            EXPECT_LT(std::fabs(d.dot(xp)) / xp.norm(), 1e-6) << to_string(shape) << " " << i;
        }
    }
}

TEST(OnhTruth, SectorsAreAnatomicalAndCoverEveryPoint) {
    for (io::Laterality eye : {io::Laterality::kOD, io::Laterality::kOS}) {
        OnhPhantomParams p = small(OnhShape::kCupped);
        p.eye = eye;
        OnhTruthOptions o = fast_options();
        o.mrw_points = 72;
        const OnhTruth t = compute_onh_truth(p, o);
        int total = 0;
        for (int n : t.mrw_sector_points) {
            EXPECT_GT(n, 0);
            total += n;
        }
        EXPECT_EQ(total, 72);
        // Nasal is grid +x for OD and -x for OS; superior is grid +y (first B-scan inferior).
        const Eigen::Vector2d c = expected_centre(p);
        for (std::size_t i = 0; i < t.bmo_points_mm.size(); ++i) {
            const double dx = t.bmo_points_mm[i].x() - c.x();
            const double dy = t.bmo_points_mm[i].y() - c.y();
            double deg = std::atan2(dy, eye == io::Laterality::kOD ? dx : -dx) * 180.0 / kPi;
            if (deg < 0.0) deg += 360.0;
            EXPECT_NEAR(t.bmo_anatomical_deg[i], deg, 1e-9);
        }
        const double expect = eye == io::Laterality::kOD ? 80.0 : 100.0;
        EXPECT_NEAR(t.bmo_orientation_anatomical_deg, expect, 1e-9);
    }
}

// ---------------------------------------------------------------------------------------------
// Geometry: the overhang

// Crossings of the meridian curve with rho = r found by a dense independent scan of the curve.
std::vector<double> dense_crossings(const OnhPhantomGeometry& g, double r) {
    std::vector<double> out;
    const double step = 1e-5;
    double prev = g.rho(0.0) - r;
    for (double s = step; s <= 2.0; s += step) {
        const double cur = g.rho(s) - r;
        if ((prev < 0.0) != (cur < 0.0)) out.push_back(g.w(s - step * cur / (cur - prev)));
        prev = cur;
    }
    std::sort(out.begin(), out.end(), std::greater<>());
    return out;
}

TEST(OnhGeometry, OverhangMeetsSomeVerticalLinesThreeTimes) {
    const OnhPhantomGeometry g(small(OnhShape::kOverhang));
    double lo = 10.0;
    double hi = 0.0;
    for (double r = 0.0; r <= 1.5; r += 0.001) {
        const auto c = g.crossings(r);
        ASSERT_TRUE(c.size() == 1 || c.size() == 3) << r;
        if (c.size() == 3) {
            lo = std::min(lo, r);
            hi = std::max(hi, r);
        }
    }
    // The preset's undercut pushes the wall 0.2 BMO radii outward at the band centre; the
    // three-crossing zone is most of that (the mouth sits above the band).
    EXPECT_GT(hi - lo, 0.1);
    EXPECT_LT(hi, 1.0);  // the undercut stays inside the BMO
    const double r = 0.5 * (lo + hi);
    const auto c = g.crossings(r);
    const auto d = dense_crossings(g, r);
    ASSERT_EQ(d.size(), 3U);
    for (std::size_t k = 0; k < 3; ++k) EXPECT_NEAR(c[k], d[k], 1e-6);  // linear interp. error
    // Point-in-region test: tissue (lip) between crossings 1 and 2, vitreous (cavity) between
    // 2 and 3, tissue below 3, vitreous above 1. A point at normalised radius r on the x axis of
    // the normalised frame:
    const Eigen::Vector2d xy = g.bmo_centre() + g.frame() * Eigen::Vector2d(r, 0.0);
    const double zb = g.bm_height(xy.x(), xy.y());
    EXPECT_FALSE(g.in_tissue(xy.x(), xy.y(), zb + c[0] + 1e-3));
    EXPECT_TRUE(g.in_tissue(xy.x(), xy.y(), zb + 0.5 * (c[0] + c[1])));
    EXPECT_FALSE(g.in_tissue(xy.x(), xy.y(), zb + 0.5 * (c[1] + c[2])));
    EXPECT_TRUE(g.in_tissue(xy.x(), xy.y(), zb + c[2] - 1e-3));
    // No height field: the cup and swollen presets never cross a vertical line twice.
    for (OnhShape shape : {OnhShape::kCupped, OnhShape::kSwollen}) {
        const OnhPhantomGeometry h(small(shape));
        for (double q = 0.0; q <= 1.5; q += 0.01) EXPECT_EQ(h.crossings(q).size(), 1U);
    }
}

TEST(OnhGeometry, RejectsBadParametersNamingTheField) {
    auto message = [](const OnhPhantomParams& p) {
        try {
            const OnhPhantomGeometry g(p);
        } catch (const UsageError& e) {
            return std::string(e.what());
        }
        return std::string();
    };
    OnhPhantomParams p = small(OnhShape::kCupped);
    p.bmo_semi_minor_mm = 1.0;
    EXPECT_NE(message(p).find("bmo_semi_major_mm"), std::string::npos);
    p = small(OnhShape::kOverhang);
    p.profile.undercut_height_mm = -0.35;  // band reaches below the cup floor
    EXPECT_NE(message(p).find("undercut_height_mm"), std::string::npos);
    p = small(OnhShape::kCupped);
    p.profile.cup_radius = 1.6;  // the cup would pass under the BM outside the opening
    p.profile.cup_depth_mm = 0.9;
    EXPECT_NE(message(p).find("profile"), std::string::npos);
    p = small(OnhShape::kCupped);
    p.bmo_offset_x_mm = 1.0;
    EXPECT_NE(message(p).find("bmo_offset_mm"), std::string::npos);
    p = small(OnhShape::kCupped);
    p.depth_px = 250;  // geometry no longer fits the image
    EXPECT_THROW((void)render_onh_scan(p), UsageError);
}

// ---------------------------------------------------------------------------------------------
// The scan

TEST(OnhScan, MetadataLikeASpectralisOnhVolume) {
    OnhPhantomParams p = small(OnhShape::kCupped);
    p.eye = io::Laterality::kOS;
    const io::Scan s = render_onh_scan(p);
    EXPECT_EQ(s.meta.version, "HSF-OCT-103");
    EXPECT_EQ(s.meta.pattern, io::ScanPattern::kVolume);
    EXPECT_EQ(s.meta.scan_pattern_code, 3);
    EXPECT_EQ(s.meta.laterality, io::Laterality::kOS);
    EXPECT_EQ(s.meta.scan_position_raw, "OS");
    EXPECT_EQ(s.meta.size_x, 64);
    EXPECT_EQ(s.meta.size_z, 496);
    EXPECT_EQ(s.num_bscans(), 25);
    EXPECT_DOUBLE_EQ(s.meta.scale_x_mm, 4.35 / 64);
    EXPECT_DOUBLE_EQ(s.meta.distance_mm, 4.35 / 24);
    EXPECT_DOUBLE_EQ(s.meta.scale_z_mm, 0.0038717);
    EXPECT_EQ(s.meta.size_x_slo, 256);
    EXPECT_EQ(s.slo.size(), 256U * 256U);
    EXPECT_TRUE(s.meta.exam_time_filetime.has_value());
    EXPECT_TRUE(s.meta.visit_date_ole.has_value());
    EXPECT_NE(s.meta.ids.patient_id.find("FAKE"), std::string::npos);
    EXPECT_TRUE(s.pixels_loaded);
    // First B-scan most inferior (largest SLO y), A-scans left to right, spacing = Distance.
    for (int b = 1; b < s.num_bscans(); ++b) {
        const auto& prev = s.bscans[static_cast<std::size_t>(b - 1)];
        const auto& cur = s.bscans[static_cast<std::size_t>(b)];
        EXPECT_NEAR(prev.start_y_mm - cur.start_y_mm, s.meta.distance_mm, 1e-12);
        EXPECT_LT(cur.start_x_mm, cur.end_x_mm);
        EXPECT_NEAR(cur.end_x_mm - cur.start_x_mm, 63 * s.meta.scale_x_mm, 1e-12);
    }
}

TEST(OnhScan, BmMissingExactlyInsideTheOpeningIlmIsTheEnvelope) {
    const OnhPhantomParams p = small(OnhShape::kOverhang, 25, 128);
    const io::Scan s = render_onh_scan(p);
    const OnhPhantomGeometry g(p);
    const double sx = p.field_mm / p.num_ascans;
    const double dy = p.field_mm / (p.num_bscans - 1);
    int missing = 0;
    int three = 0;
    for (int b = 0; b < p.num_bscans; ++b) {
        const io::BScan& bs = s.bscans[static_cast<std::size_t>(b)];
        ASSERT_EQ(bs.num_seg(), 2);
        for (int a = 0; a < p.num_ascans; ++a) {
            const auto ai = static_cast<std::size_t>(a);
            const double x = a * sx;
            const double y = b * dy;
            const bool inside = inside_ellipse(p, x, y);
            EXPECT_EQ(std::isnan(bs.seg[1][ai]), inside) << b << " " << a;
            missing += inside ? 1 : 0;
            ASSERT_FALSE(std::isnan(bs.seg[0][ai]));
            // The device ILM is the first tissue from the top: every ILM crossing of this
            // column lies at or below it, and it is one of them (float storage: 1e-3 px).
            const auto h = g.ilm_heights(x, y);
            three += h.size() == 3 ? 1 : 0;
            const double top_px = -h.front() / p.scale_z_mm;
            EXPECT_NEAR(bs.seg[0][ai], top_px, 1e-3);
            for (double z : h) EXPECT_GE(-z / p.scale_z_mm, bs.seg[0][ai] - 1e-3);
            // Above the device line there is no tissue (checked 0.5 and 5 px above).
            for (double up : {0.5, 5.0}) {
                EXPECT_FALSE(g.in_tissue(x, y, -(bs.seg[0][ai] - up) * p.scale_z_mm));
            }
        }
    }
    EXPECT_GT(missing, 0);
    EXPECT_GT(three, 0);  // the grid does sample the overhang
}

TEST(OnhScan, SameSeedSameFileOtherSeedOtherSpeckle) {
    OnhPhantomParams p = small(OnhShape::kSwollen, 9, 32);
    const io::Scan a = render_onh_scan(p);
    const io::Scan b = render_onh_scan(p);
    p.seed = 2;
    const io::Scan c = render_onh_scan(p);
    std::size_t differ = 0;
    std::size_t n = 0;
    for (std::size_t k = 0; k < a.bscans.size(); ++k) {
        EXPECT_EQ(a.bscans[k].pixels, b.bscans[k].pixels);
        EXPECT_EQ(a.bscans[k].seg[0], c.bscans[k].seg[0]);
        for (std::size_t i = 0; i < a.bscans[k].pixels.size(); ++i) {
            differ += a.bscans[k].pixels[i] != c.bscans[k].pixels[i] ? 1 : 0;
            ++n;
        }
    }
    EXPECT_EQ(a.slo, b.slo);
    EXPECT_GT(differ, n * 9 / 10);  // speckle is independent per pixel
    // The truth file is reproducible too (no timings or dates in it).
    const OnhTruthOptions o = fast_options();
    EXPECT_EQ(onh_truth_to_json(p, o, compute_onh_truth(p, o)).dump(),
              onh_truth_to_json(p, o, compute_onh_truth(p, o)).dump());
}

// Mean display value (v^0.25) a few pixels below the true ILM vs a few pixels above it.
// Expected: vitreous 2e-4 -> ~0.12; tissue within 3 px of the ILM >= 0.2 linear -> ~0.7;
// speckle Gamma(4) lowers E[v^0.25] by ~5 %. A margin of 0.3 is half the expected contrast.
// Checked at the top ILM everywhere and at the floor of the overhang's cavity, where a level
// set must find the ILM the device line cannot see.
TEST(OnhScan, TissueBelowTheTrueIlmIsBrighterThanTheVitreousAbove) {
    const OnhPhantomParams p = small(OnhShape::kOverhang, 25, 128);
    const io::Scan s = render_onh_scan(p);
    const OnhPhantomGeometry g(p);
    const double sx = p.field_mm / p.num_ascans;
    const double dy = p.field_mm / (p.num_bscans - 1);
    double top_below = 0.0;
    double top_above = 0.0;
    int n_top = 0;
    double cav_below = 0.0;
    double cav_above = 0.0;
    int n_cav = 0;
    for (int b = 0; b < p.num_bscans; ++b) {
        const auto& px = s.bscans[static_cast<std::size_t>(b)].pixels;
        for (int a = 0; a < p.num_ascans; ++a) {
            const auto h = g.ilm_heights(a * sx, b * dy);
            auto value = [&](double depth_px) {
                const auto row = static_cast<std::size_t>(std::lround(depth_px));
                return display(
                    px[row * static_cast<std::size_t>(p.num_ascans) + static_cast<std::size_t>(a)]);
            };
            const double top = -h.front() / p.scale_z_mm;
            for (int k = 2; k <= 4; ++k) {
                top_below += value(top + k);
                top_above += value(top - k);
                ++n_top;
            }
            if (h.size() == 3) {
                const double roof = -h[1] / p.scale_z_mm;
                const double floor = -h[2] / p.scale_z_mm;
                if (floor - roof < 10.0) continue;
                for (int k = 2; k <= 4; ++k) {
                    cav_below += value(floor + k);
                    cav_above += value(floor - k);
                    ++n_cav;
                }
            }
        }
    }
    ASSERT_GT(n_cav, 0);
    EXPECT_GT(top_below / n_top - top_above / n_top, 0.3);
    EXPECT_GT(cav_below / n_cav - cav_above / n_cav, 0.3);
    EXPECT_LT(top_above / n_top, 0.2);  // dark vitreous
}

TEST(OnhScan, WrittenFileReadsBackExactly) {
    const OnhPhantomParams p = small(OnhShape::kCupped, 9, 32);
    const io::Scan s = render_onh_scan(p);
    std::stringstream buf;
    io::write_vol(s, buf);
    const std::string bytes = buf.str();
    std::istringstream in(bytes);
    io::ReadOptions ro;
    ro.pixels = true;
    const io::Scan r = io::read_vol(in, bytes.size(), "phantom.vol", ro);
    EXPECT_EQ(r.meta.size_x, 32);
    EXPECT_EQ(r.meta.size_z, 496);
    EXPECT_EQ(r.num_bscans(), 9);
    EXPECT_DOUBLE_EQ(r.meta.scale_x_mm, s.meta.scale_x_mm);
    EXPECT_DOUBLE_EQ(r.meta.distance_mm, s.meta.distance_mm);
    EXPECT_EQ(r.meta.laterality, io::Laterality::kOD);
    EXPECT_EQ(r.slo, s.slo);
    for (std::size_t b = 0; b < s.bscans.size(); ++b) {
        EXPECT_EQ(r.bscans[b].pixels, s.bscans[b].pixels);
        for (std::size_t a = 0; a < 32; ++a) {
            EXPECT_EQ(std::isnan(r.bscans[b].seg[1][a]), std::isnan(s.bscans[b].seg[1][a]));
            if (!std::isnan(s.bscans[b].seg[1][a])) {
                EXPECT_EQ(r.bscans[b].seg[1][a], s.bscans[b].seg[1][a]);
            }
            EXPECT_EQ(r.bscans[b].seg[0][a], s.bscans[b].seg[0][a]);
        }
    }
}

// ---------------------------------------------------------------------------------------------
// The command

TEST(PhantomOnhCommand, WritesTheVolAndItsTruth) {
    test::TempDir dir;
    const auto vol = dir / "eye.vol";
    const test::RunResult r = test::run_octshape(
        "-q phantom onh --shape overhang --eye OS --bscans 9 --ascans 48 --mrw-points 16 -o '" +
        vol.string() + "'");
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const auto truth_path = dir / "eye.truth.json";
    ASSERT_TRUE(std::filesystem::exists(truth_path));
    std::ifstream tf(truth_path);
    const nlohmann::json j = nlohmann::json::parse(tf);
    EXPECT_EQ(j["provenance"]["version"], kVersion);
    EXPECT_EQ(j["options"]["shape"], "overhang");
    EXPECT_EQ(j["options"]["eye"], "OS");
    EXPECT_EQ(j["options"]["bscans"], 9);
    for (const char* key : {"cup_volume_mm3", "conht_mm", "bmo_volume_mm3", "total_volume_mm3",
                            "annular_volume_mm3", "bmo_area_mm2", "mrw_mean_mm", "mrw_area_mm2",
                            "bending_energy", "bmo_centre_mm", "mrw_sector_mm"}) {
        EXPECT_TRUE(j["truth"].contains(key)) << key;
    }
    EXPECT_GT(j["truth"]["cup_volume_mm3"].get<double>(), 0.0);
    EXPECT_EQ(j["bmo_points"].size(), 16U);
    std::ifstream vf(vol, std::ios::binary);
    const io::Scan s = io::read_vol(vf, std::filesystem::file_size(vol), vol.string());
    EXPECT_EQ(s.num_bscans(), 9);
    EXPECT_EQ(s.meta.size_x, 48);
    EXPECT_EQ(s.meta.laterality, io::Laterality::kOS);
    // No temporary files left beside the outputs.
    int files = 0;
    for ([[maybe_unused]] const auto& e : std::filesystem::directory_iterator(dir.path())) ++files;
    EXPECT_EQ(files, 2);
}

TEST(PhantomOnhCommand, BadOptionIsAUsageErrorAndWritesNothing) {
    test::TempDir dir;
    const auto vol = dir / "eye.vol";
    const test::RunResult r = test::run_octshape(
        "phantom onh --bscans 9 --ascans 48 --bmo-axes-mm 0.5 0.9 -o '" + vol.string() + "'");
    EXPECT_EQ(r.exit_code, 64) << r.err;
    EXPECT_NE(r.err.find("bmo_semi_major_mm"), std::string::npos) << r.err;
    EXPECT_FALSE(std::filesystem::exists(vol));
    EXPECT_FALSE(std::filesystem::exists(dir / "eye.truth.json"));
    EXPECT_EQ(test::run_octshape("phantom").exit_code, 64);  // a subcommand is required
}

}  // namespace
}  // namespace octshape::retina
