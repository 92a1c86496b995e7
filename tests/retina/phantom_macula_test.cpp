// The macula phantom's truth against checks that do not share its formulas: dense evaluation of
// the generating curves, quadrature of the generated surface, polar-coordinate geometry, and the
// sampled segmentation against T(r, theta) with the anatomical angle computed here from the
// documented convention (not from the generator's frame).

#include "octshape/retina/phantom_macula.h"

#include <cmath>
#include <fstream>
#include <numbers>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "octshape/error.h"
#include "octshape/io/vol.h"
#include "test_paths.h"

namespace octshape::retina {
namespace {

constexpr double kPi = std::numbers::pi;
constexpr double kDeg = 180.0 / kPi;

// Small, fast phantom: 31 B-scans x 128 A-scans over the full field, no pixels.
MaculaPhantomParams small(MaculaFamily family, io::Laterality eye = io::Laterality::kOD) {
    MaculaPhantomParams p;
    p.family = family;
    p.eye = eye;
    p.num_bscans = 31;
    p.size_x = 128;
    p.pixels = false;
    return p;
}

Eigen::Vector2d bez_d(const std::array<Eigen::Vector2d, 4>& c, double t) {
    const double u = 1.0 - t;
    return 3 * (u * u * (c[1] - c[0]) + 2 * u * t * (c[2] - c[1]) + t * t * (c[3] - c[2]));
}

Eigen::Vector2d bez(const std::array<Eigen::Vector2d, 4>& c, double t) {
    const double u = 1.0 - t;
    return u * u * u * c[0] + 3 * u * u * t * c[1] + 3 * u * t * t * c[2] + t * t * t * c[3];
}

// Composite Simpson of f over [a, b] with m (even) intervals.
template <typename F>
double simpson(F f, double a, double b, int m) {
    const double h = (b - a) / m;
    double s = f(a) + f(b);
    for (int i = 1; i < m; ++i) s += (i % 2 ? 4.0 : 2.0) * f(a + i * h);
    return s * h / 3.0;
}

// Anatomical angle (deg) of a grid direction by the documented convention: OD grid +x nasal,
// OS grid +x temporal, grid +y superior for both.
double anatomical_deg(io::Laterality eye, double dx, double dy) {
    const double nasal = eye == io::Laterality::kOS ? -dx : dx;
    double a = std::atan2(dy, nasal) * kDeg;
    if (a < 0.0) a += 360.0;
    return a;
}

TEST(MaculaTruth, BezierMaxSlopeClosedFormMatchesDenseEvaluation) {
    for (const bool flat : {false, true}) {
        MaculaPhantomParams p = small(MaculaFamily::kBezier);
        p.flat = flat;
        const MaculaTruth t = macula_truth(p);
        ASSERT_EQ(t.half_lines.size(), 24U);
        double mean = 0.0;
        for (const auto& h : t.half_lines) {
            const auto c = bezier_profile(h.angle_deg, flat).interior();
            // Dense slope dy/dx = y'(t)/x'(t) of the curve on 200000 steps of t.
            constexpr int kN = 200000;
            double best = -1.0;
            Eigen::Vector2d best_q;
            for (int k = 1; k < kN; ++k) {
                const double tk = static_cast<double>(k) / kN;
                const Eigen::Vector2d d = bez_d(c, tk);
                const double s = d.y() / d.x();
                if (s > best) {
                    best = s;
                    best_q = bez(c, tk);
                }
            }
            // The slope is flat at its maximum: half a t-step (2.5e-6) changes it by
            // ~|s''| 3e-12 < 1e-11, far below 1e-8 deg.
            EXPECT_NEAR(h.max_slope_deg, std::atan(best) * kDeg, 1e-8) << h.angle_deg;
            // The dense arg-max is within half a t-step: the point within |Q'| 2.5e-6 < 1e-5 mm
            // (|Q'| <= 3 max(alpha, w - alpha - beta, beta) < 3 mm).
            EXPECT_NEAR(h.slope_point[0], best_q.x(), 1e-5);
            EXPECT_NEAR(h.slope_point[1], best_q.y(), 1e-5);
            mean += h.max_slope_deg / 24.0;
        }
        EXPECT_NEAR(t.max_pit_slope_deg, mean, 1e-12);
    }
}

TEST(MaculaTruth, BezierVolumesMatchQuadratureOfTheSurface) {
    for (const double r_u : {0.5, 1.5}) {  // 1.5 mm passes every rim: exterior counts too
        const MaculaPhantomParams p = small(MaculaFamily::kBezier);
        MaculaTruthOptions o;
        o.inner_radius_mm = r_u;
        const MaculaTruth t = macula_truth(p, o);
        double vr = 0.0;
        double vir = 0.0;
        for (const auto& h : t.half_lines) {
            // T(r) is evaluated through the generator's surface (inverting x(t)); Simpson with
            // 4000 intervals on a smooth integrand errs by ~h^4 |f''''| < 1e-12 mm^3.
            auto f = [&](double r) { return macula_thickness_mm(p, r, h.angle_deg) * r; };
            vr += simpson(f, 0.0, h.rim_radius_mm, 4000);
            // Across the rim the integrand has a kink in its 2nd derivative: split there.
            if (r_u <= h.rim_radius_mm) {
                vir += simpson(f, 0.0, r_u, 4000);
            } else {
                vir += simpson(f, 0.0, h.rim_radius_mm, 4000) +
                       simpson(f, h.rim_radius_mm, r_u, 4000);
            }
        }
        const double w = 2.0 * kPi / 24.0;
        EXPECT_NEAR(t.rim_volume_mm3, w * vr, 1e-9);
        EXPECT_NEAR(t.inner_rim_volume_mm3, w * vir, 1e-9) << "r_u " << r_u;
        EXPECT_NEAR(t.pit_volume_mm3, t.rim.area_mm2 * t.rim_height_mm - t.rim_volume_mm3,
                    1e-15);
    }
}

TEST(MaculaTruth, RimIsTheMaximumOfEachHalfLineWithinR) {
    for (const auto family : {MaculaFamily::kBezier, MaculaFamily::kScheibe}) {
        for (const bool flat : {false, true}) {
            MaculaPhantomParams p = small(family);
            p.flat = flat;
            const MaculaTruth t = macula_truth(p);
            for (const auto& h : t.half_lines) {
                // Dense search on [0, 2 mm] with a 0.1 um step: the maximum is quadratic there,
                // so the height agrees to ~|T''| (5e-5)^2 < 1e-9 mm.
                double best = -1.0;
                double best_r = 0.0;
                for (int k = 0; k <= 20000; ++k) {
                    const double r = 2.0 * k / 20000;
                    const double v = macula_thickness_mm(p, r, h.angle_deg);
                    if (v > best) {
                        best = v;
                        best_r = r;
                    }
                }
                EXPECT_NEAR(h.rim_height_mm, best, 1e-9);
                EXPECT_NEAR(h.rim_radius_mm, best_r, 2e-4);  // T'' ~ -0.3/mm: sqrt(1e-9/0.15)
                EXPECT_NEAR(macula_thickness_mm(p, h.rim_radius_mm, h.angle_deg), h.rim_height_mm,
                            1e-14);
            }
        }
    }
}

TEST(MaculaTruth, RotationAndRadialScaleTransformTheEye) {
    // rotation_deg turns the eye about the fovea, radial_scale stretches its pit: inside the
    // rim, T(r, theta) = T0(r / k, theta - rot) for both families (the Bezier exterior keeps
    // its 7 mm end, so only the interior obeys the plain stretch). The truth follows: rim
    // radius k r0, rim height unchanged, slope tan(s) = tan(s0) / k.
    for (const auto family : {MaculaFamily::kBezier, MaculaFamily::kScheibe}) {
        const MaculaPhantomParams base = small(family);
        MaculaPhantomParams p = base;
        p.rotation_deg = 2.5;
        p.radial_scale = 1.1;
        const MaculaTruth t = macula_truth(p);
        for (const auto& h : t.half_lines) {
            const double th0 = h.angle_deg - 2.5;
            for (const double r : {0.0, 0.3, 0.7, 0.95 * h.rim_radius_mm}) {
                EXPECT_NEAR(macula_thickness_mm(p, r, h.angle_deg),
                            macula_thickness_mm(base, r / 1.1, th0), 1e-12);
            }
            double best = -1.0;
            double best_r = 0.0;
            for (int k = 0; k <= 20000; ++k) {  // dense maximum, as in RimIsTheMaximum...
                const double r = 2.0 * k / 20000;
                const double v = macula_thickness_mm(base, r, th0);
                if (v > best) {
                    best = v;
                    best_r = r;
                }
            }
            EXPECT_NEAR(h.rim_radius_mm, 1.1 * best_r, 1.1 * 2e-4);
            EXPECT_NEAR(h.rim_height_mm, best, 1e-9);
        }
    }
}

TEST(MaculaTruth, PitFlatRadiusIsWhereTheProfileRisesTau) {
    for (const auto family : {MaculaFamily::kBezier, MaculaFamily::kScheibe}) {
        for (const bool flat : {false, true}) {
            MaculaPhantomParams p = small(family);
            p.flat = flat;
            const MaculaTruth t = macula_truth(p);
            double sum = 0.0;
            for (const auto& h : t.half_lines) {
                const double rf = h.pit_flat_radius_mm;
                EXPECT_NEAR(macula_thickness_mm(p, rf, h.angle_deg), t.cft_mm + 0.005, 1e-12);
                EXPECT_LT(macula_thickness_mm(p, 0.99 * rf, h.angle_deg), t.cft_mm + 0.005);
                sum += rf;
            }
            EXPECT_NEAR(t.pit_flat_diameter_mm, 2.0 * sum / 24.0, 1e-14);
        }
    }
}

TEST(MaculaTruth, ScheibeMaxSlopeMatchesDenseSearch) {
    for (const bool flat : {false, true}) {
        MaculaPhantomParams p = small(MaculaFamily::kScheibe);
        p.flat = flat;
        const MaculaTruth t = macula_truth(p);
        for (const auto& h : t.half_lines) {
            // Central differences (step 1e-6 mm) on a 1 um grid: the slope maximum is flat,
            // so the dense maximum agrees to ~|T'''| (0.5 um)^2 ~ 1e-12; 1e-6 deg is ample.
            double best = -1.0;
            double best_r = 0.0;
            for (int k = 1; k < 2000; ++k) {
                const double r = h.rim_radius_mm * k / 2000;
                const double s = (macula_thickness_mm(p, r + 1e-6, h.angle_deg) -
                                  macula_thickness_mm(p, r - 1e-6, h.angle_deg)) /
                                 2e-6;
                if (s > best) {
                    best = s;
                    best_r = r;
                }
            }
            EXPECT_NEAR(h.max_slope_deg, std::atan(best) * kDeg, 1e-5) << h.angle_deg;
            EXPECT_NEAR(h.slope_point[0], best_r, h.rim_radius_mm / 2000);
            EXPECT_FALSE(h.alpha_mm.has_value());
        }
        EXPECT_FALSE(t.alpha_mean_mm.has_value());
    }
}

TEST(MaculaTruth, ScheibeVolumeQuadratureConverges) {
    const MaculaPhantomParams p = small(MaculaFamily::kScheibe);
    MaculaTruthOptions coarse;
    coarse.quadrature_panels = 8;
    const MaculaTruth a = macula_truth(p, coarse);
    const MaculaTruth b = macula_truth(p);  // 256 -> 512 panels
    // An independent Simpson rule on 20000 intervals (error ~1e-13 away from r = 0; near 0 the
    // integrand behaves like r^(gamma+1), gamma >= 2, still smooth enough for h^4).
    double v = 0.0;
    for (const auto& h : b.half_lines) {
        v += simpson([&](double r) { return macula_thickness_mm(p, r, h.angle_deg) * r; }, 0.0,
                     h.rim_radius_mm, 20000);
    }
    v *= 2.0 * kPi / 24.0;
    EXPECT_NEAR(b.rim_volume_mm3, v, 1e-10);
    // The reported error (change on halving the panels) bounds the real one and shrinks.
    auto err = [](const MaculaTruth& t) {
        for (const auto& [name, acc] : t.accuracy) {
            if (name == "rim_volume_mm3") return acc.abs_error;
        }
        return -1.0;
    };
    EXPECT_GE(err(a), std::fabs(a.rim_volume_mm3 - v) * 0.5);
    EXPECT_LT(err(b), 1e-10);
    EXPECT_LT(err(b), err(a));
}

TEST(MaculaTruth, DisksAgreeWithPolarGeometry) {
    const MaculaPhantomParams p = small(MaculaFamily::kBezier);
    const MaculaTruth t = macula_truth(p);
    const auto& hl = t.half_lines;
    const double step = 2.0 * kPi / 24.0;
    double a2 = 0.0;
    double d = 0.0;
    for (std::size_t i = 0; i < 24; ++i) {
        // Polygon area in polar form; opposite points: radii add, heights differ.
        a2 += 0.5 * hl[i].rim_radius_mm * hl[(i + 1) % 24].rim_radius_mm * std::sin(step);
        if (i < 12) {
            d += std::hypot(hl[i].rim_radius_mm + hl[i + 12].rim_radius_mm,
                            hl[i].rim_height_mm - hl[i + 12].rim_height_mm) /
                 12.0;
        }
    }
    EXPECT_NEAR(t.rim.diameter_mm, d, 1e-12);
    EXPECT_NEAR(t.rim.area_mm2, a2 / t.rim.normal[2], 1e-12);
    EXPECT_GT(t.rim.normal[2], 0.99);
    EXPECT_NEAR(t.rim.semi_axes_mm[0], std::sqrt(2.0 * t.rim.eigenvalues_mm2[0]), 1e-15);
    EXPECT_GE(t.rim.eigenvalues_mm2[0], t.rim.eigenvalues_mm2[1]);
    EXPECT_GE(t.rim.eigenvalues_mm2[1], t.rim.eigenvalues_mm2[2]);
    // The pit-flat points share one height: their disk is horizontal.
    EXPECT_NEAR(t.pit_flat.normal[2], 1.0, 1e-12);
    EXPECT_NEAR(t.rim_height_mm - t.cft_mm, t.pit_depth_mm, 1e-15);
}

TEST(MaculaTruth, LeftEyeIsTheMirroredRightEye) {
    for (const auto family : {MaculaFamily::kBezier, MaculaFamily::kScheibe}) {
        MaculaPhantomParams od = small(family);
        od.fovea_dx_mm = 0.1;
        MaculaPhantomParams os = small(family, io::Laterality::kOS);
        os.fovea_dx_mm = -0.1;
        const MaculaTruth a = macula_truth(od);
        const MaculaTruth b = macula_truth(os);
        EXPECT_NEAR(a.centre_x_mm + b.centre_x_mm, 767 * 0.01169, 1e-12);
        for (const auto& [x, y] :
             {std::pair{a.rim_height_mm, b.rim_height_mm},
              {a.max_pit_slope_deg, b.max_pit_slope_deg},
              {a.rim.diameter_mm, b.rim.diameter_mm}, {a.rim.area_mm2, b.rim.area_mm2},
              {a.slope.area_mm2, b.slope.area_mm2}, {a.pit_flat.area_mm2, b.pit_flat.area_mm2},
              {a.rim.eigenvalues_mm2[1], b.rim.eigenvalues_mm2[1]},
              {a.rim_volume_mm3, b.rim_volume_mm3}, {a.pit_volume_mm3, b.pit_volume_mm3},
              {a.inner_rim_volume_mm3, b.inner_rim_volume_mm3}}) {
            EXPECT_NEAR(x, y, 1e-12);
        }
        // Normals: mirrored in grid x.
        EXPECT_NEAR(a.rim.normal[0], -b.rim.normal[0], 1e-9);
        EXPECT_NEAR(a.rim.normal[1], b.rim.normal[1], 1e-9);
        EXPECT_GT(std::fabs(a.rim.normal[0]), 1e-4);  // the rim disk is tilted nasally
        // Thickness at grid points mirrored: OD A-scan a = OS A-scan (n - 1 - a).
        const MaculaPhantom pa = make_macula_phantom(od);
        const MaculaPhantom pb = make_macula_phantom(os);
        const double sz = pa.scan.meta.scale_z_mm;
        for (int bi = 0; bi < 31; bi += 3) {
            for (int ai = 0; ai < 128; ++ai) {
                const double ta = (pa.scan.depth_px(1, bi, ai) - pa.scan.depth_px(0, bi, ai)) * sz;
                const double tb =
                    (pb.scan.depth_px(1, bi, 127 - ai) - pb.scan.depth_px(0, bi, 127 - ai)) * sz;
                ASSERT_NEAR(ta, tb, 1e-6) << bi << " " << ai;  // float depths ~300 px: 2e-7 mm
            }
        }
    }
}

TEST(MaculaPhantom, SegmentationReproducesTheThicknessSurface) {
    for (const auto eye : {io::Laterality::kOD, io::Laterality::kOS}) {
        MaculaPhantomParams p = small(MaculaFamily::kBezier, eye);
        p.fovea_dx_mm = 0.037;  // the centre is not on a grid node
        p.fovea_dy_mm = -0.051;
        const MaculaPhantom ph = make_macula_phantom(p);
        const io::Scan& s = ph.scan;
        const double sx = s.meta.scale_x_mm;
        const double d = s.meta.distance_mm;
        EXPECT_NEAR(sx, 767 * 0.01169 / 127, 1e-15);
        EXPECT_NEAR(d, 7.5 / 30, 1e-15);
        const double cx = 127 * sx / 2 + 0.037;
        const double cy = 30 * d / 2 - 0.051;
        EXPECT_NEAR(ph.truth.centre_x_mm, cx, 1e-12);
        EXPECT_NEAR(ph.truth.centre_y_mm, cy, 1e-12);
        double worst = 0.0;
        for (int b = 0; b < 31; ++b) {
            for (int a = 0; a < 128; ++a) {
                const float ilm = s.depth_px(0, b, a);
                const float bm = s.depth_px(1, b, a);
                ASSERT_TRUE(io::is_valid(ilm) && io::is_valid(bm));
                ASSERT_GT(ilm, 0.0F);
                ASSERT_LT(bm, static_cast<float>(s.meta.size_z));
                const double dx = a * sx - cx;
                const double dy = b * d - cy;
                const double want = macula_thickness_mm(p, std::hypot(dx, dy),
                                                        anatomical_deg(eye, dx, dy));
                worst = std::max(worst, std::fabs((bm - ilm) * s.meta.scale_z_mm - want));
            }
        }
        // Two float depths of <= 496 px: half an ulp each is 1.5e-5 px = 6e-8 mm.
        EXPECT_LT(worst, 2e-7);
    }
}

TEST(MaculaPhantom, NasalHalfLineLiesWhereTheConventionSays) {
    // OD: nasal = grid +x; OS: nasal = grid -x. The rim of the nasal half-line is at
    // r_rim(0 deg) from the centre; a sample there shows its height.
    for (const auto eye : {io::Laterality::kOD, io::Laterality::kOS}) {
        MaculaPhantomParams p = small(MaculaFamily::kBezier, eye);
        p.size_x = 768;
        const MaculaTruth t = macula_truth(p);
        const BezierProfile nasal = bezier_profile(0.0, false);
        const BezierProfile temporal = bezier_profile(180.0, false);
        ASSERT_GT(nasal.rim_height_mm - temporal.rim_height_mm, 0.02);
        EXPECT_DOUBLE_EQ(t.half_lines[0].rim_height_mm, nasal.rim_height_mm);
        EXPECT_DOUBLE_EQ(t.half_lines[12].rim_height_mm, temporal.rim_height_mm);
        const MaculaPhantom ph = make_macula_phantom(p);
        const double sx = ph.scan.meta.scale_x_mm;
        const double sign = eye == io::Laterality::kOD ? 1.0 : -1.0;
        const int a =
            static_cast<int>(std::lround((t.centre_x_mm + sign * nasal.rim_radius_mm) / sx));
        const double th = (ph.scan.depth_px(1, 15, a) - ph.scan.depth_px(0, 15, a)) *
                          ph.scan.meta.scale_z_mm;
        // Within half an A-scan (6 um) of the rim the height is within ~1e-5 mm of its maximum.
        EXPECT_NEAR(th, nasal.rim_height_mm, 1e-4);
        // And the B-scans are placed so that the first one is the most inferior.
        EXPECT_GT(ph.scan.bscans.front().start_y_mm, ph.scan.bscans.back().start_y_mm);
        EXPECT_LT(ph.scan.bscans.front().start_x_mm, ph.scan.bscans.front().end_x_mm);
    }
}

TEST(MaculaPhantom, NoiseHasTheRequestedSd) {
    MaculaPhantomParams p = small(MaculaFamily::kScheibe);
    const MaculaPhantom clean = make_macula_phantom(p);
    p.noise_um = 3.9;
    const MaculaPhantom noisy = make_macula_phantom(p);
    const double sz = p.scale_z_mm;
    double s[2] = {0, 0};
    double s2[2] = {0, 0};
    double cross = 0.0;
    int n = 0;
    for (int b = 0; b < 31; ++b) {
        for (int a = 0; a < 128; ++a) {
            const double e0 = (noisy.scan.depth_px(0, b, a) - clean.scan.depth_px(0, b, a)) * sz;
            const double e1 = (noisy.scan.depth_px(1, b, a) - clean.scan.depth_px(1, b, a)) * sz;
            s[0] += e0;
            s[1] += e1;
            s2[0] += e0 * e0;
            s2[1] += e1 * e1;
            cross += e0 * e1;
            ++n;
        }
    }
    const double sigma = 3.9e-3;
    for (int k = 0; k < 2; ++k) {
        const double mean = s[k] / n;
        const double sd = std::sqrt(s2[k] / n - mean * mean);
        // n = 3968: SE of the mean sigma/sqrt(n), of the SD sigma/sqrt(2n); 5 SE each.
        EXPECT_NEAR(mean, 0.0, 5.0 * sigma / std::sqrt(n));
        EXPECT_NEAR(sd, sigma, 5.0 * sigma / std::sqrt(2.0 * n));
    }
    // ILM and BM noise independent: correlation within 5 / sqrt(n).
    EXPECT_LT(std::fabs(cross / n) / (sigma * sigma), 5.0 / std::sqrt(n));
}

TEST(MaculaPhantom, MissingFractionAsRequestedWithEdgeBlocks) {
    MaculaPhantomParams p = small(MaculaFamily::kBezier);
    p.missing_fraction = 0.1;
    const MaculaPhantom ph = make_macula_phantom(p);
    const int total = 31 * 128;
    const double want = std::round(0.1 * total) / total;
    EXPECT_NEAR(ph.scan.valid_fraction(0), 1.0 - want, 1e-12);
    EXPECT_NEAR(ph.scan.valid_fraction(1), 1.0 - want, 1e-12);
    int edge = 0;
    int middle = 0;
    int first_missing = 0;
    for (int b = 0; b < 31; ++b) {
        first_missing += io::is_valid(ph.scan.depth_px(0, b, 0)) ? 0 : 1;
        for (int a = 0; a < 128; ++a) {
            const bool miss = !io::is_valid(ph.scan.depth_px(0, b, a));
            EXPECT_EQ(miss, !io::is_valid(ph.scan.depth_px(1, b, a)));
            if (miss) ++(a < 13 || a >= 115 ? edge : middle);
        }
    }
    // Half the missing values sit in edge blocks (2 x 10 % of the columns): far denser there.
    EXPECT_GT(edge / 26.0, 3.0 * middle / 102.0);
    EXPECT_GT(first_missing, 10);
}

TEST(MaculaPhantom, DeterministicForASeed) {
    MaculaPhantomParams p = small(MaculaFamily::kBezier);
    p.size_x = 64;
    p.num_bscans = 5;
    p.pixels = true;
    p.noise_um = 2.0;
    p.missing_fraction = 0.05;
    p.vessels = 4;
    const MaculaPhantom a = make_macula_phantom(p);
    const MaculaPhantom b = make_macula_phantom(p);
    p.seed = 2;
    const MaculaPhantom c = make_macula_phantom(p);
    for (int i = 0; i < 5; ++i) {
        const auto& x = a.scan.bscans[static_cast<std::size_t>(i)];
        const auto& y = b.scan.bscans[static_cast<std::size_t>(i)];
        EXPECT_EQ(x.pixels, y.pixels);
        for (std::size_t k = 0; k < x.seg.size(); ++k) {
            for (std::size_t j = 0; j < x.seg[k].size(); ++j) {
                const float u = x.seg[k][j];
                const float v = y.seg[k][j];
                EXPECT_TRUE((std::isnan(u) && std::isnan(v)) || u == v);
            }
        }
        EXPECT_NE(x.pixels, c.scan.bscans[static_cast<std::size_t>(i)].pixels);
    }
    EXPECT_EQ(a.scan.slo, b.scan.slo);
}

TEST(MaculaPhantom, VesselsRaiseTheIlmAFewMicronsAwayFromThePit) {
    MaculaPhantomParams p = small(MaculaFamily::kBezier);
    p.vessels = 6;
    const MaculaPhantom ph = make_macula_phantom(p);
    const double sx = ph.scan.meta.scale_x_mm;
    const double d = ph.scan.meta.distance_mm;
    int raised = 0;
    for (int b = 0; b < 31; ++b) {
        for (int a = 0; a < 128; ++a) {
            const double dx = a * sx - ph.truth.centre_x_mm;
            const double dy = b * d - ph.truth.centre_y_mm;
            const double r = std::hypot(dx, dy);
            const double extra = (ph.scan.depth_px(1, b, a) - ph.scan.depth_px(0, b, a)) *
                                     ph.scan.meta.scale_z_mm -
                                 macula_thickness_mm(p, r, anatomical_deg(p.eye, dx, dy));
            EXPECT_GT(extra, -1e-6);
            EXPECT_LT(extra, 6 * 0.008 + 1e-6);  // at most 8 um per crossing band
            if (extra > 1e-4) {
                ++raised;
                EXPECT_GT(r, 0.9);  // bands lie >= 1 mm out, half-width <= 60 um
            }
        }
    }
    EXPECT_GT(raised, 20);
}

TEST(MaculaPhantom, LineScanThroughTheFovea) {
    MaculaPhantomParams p;
    p.line = true;
    p.pixels = true;
    p.fovea_dx_mm = 0.2;
    const MaculaPhantom ph = make_macula_phantom(p);
    EXPECT_EQ(ph.scan.num_bscans(), 1);
    EXPECT_EQ(ph.scan.meta.pattern, io::ScanPattern::kLine);
    EXPECT_EQ(ph.scan.meta.distance_mm, 0.0);
    EXPECT_TRUE(ph.scan.grids.empty());
    ASSERT_EQ(ph.truth.half_lines.size(), 2U);
    EXPECT_EQ(ph.truth.half_lines[1].angle_deg, 180.0);
    EXPECT_TRUE(ph.truth.line_scan);
    // The minimum of the sampled thickness is at the fovea (within one A-scan).
    double best = 1e9;
    int best_a = -1;
    for (int a = 0; a < 768; ++a) {
        const double th = (ph.scan.depth_px(1, 0, a) - ph.scan.depth_px(0, 0, a)) * p.scale_z_mm;
        if (th < best) {
            best = th;
            best_a = a;
        }
    }
    EXPECT_NEAR(best_a * ph.scan.meta.scale_x_mm, ph.truth.centre_x_mm, ph.scan.meta.scale_x_mm);
    const auto j = macula_truth_json(ph.truth, p, {});
    EXPECT_FALSE(j["parameters"].contains("rim_volume_mm3"));
    EXPECT_TRUE(j["parameters"].contains("pit_depth_mm"));
    // The pixels look like a scan: dark vitreous above the ILM, bright RPE at BM.
    const auto& bs = ph.scan.bscans[0];
    const int a = 100;
    const int ilm = static_cast<int>(bs.seg[0][a]);
    const int bm = static_cast<int>(bs.seg[1][a]);
    double vit = 0.0;
    double rpe = 0.0;
    auto px = [&](int z) { return bs.pixels[static_cast<std::size_t>(z * 768 + a)]; };
    for (int z = ilm - 40; z < ilm - 20; ++z) vit += px(z);
    for (int z = bm - 3; z < bm - 1; ++z) rpe += px(z);
    EXPECT_GT(rpe / 2, 100 * vit / 20);
}

TEST(MaculaPhantom, EtdrsGridCentreIsTheFoveaPlusTheHint) {
    MaculaPhantomParams p = small(MaculaFamily::kBezier, io::Laterality::kOS);
    p.fovea_dx_mm = 0.2;
    p.fovea_dy_mm = 0.1;
    const MaculaPhantom ph = make_macula_phantom(p);
    ASSERT_EQ(ph.scan.grids.size(), 1U);
    const auto& g = ph.scan.grids[0];
    EXPECT_EQ(g.type, 3);
    // SLO position of the fovea from the B-scan placement: x from the first A-scan to the
    // right, y up from the first (lowest) B-scan.
    const auto& b0 = ph.scan.bscans[0];
    EXPECT_NEAR(g.centre_x_slo_mm, b0.start_x_mm + ph.truth.centre_x_mm + p.grid_hint_dx_mm, 1e-9);
    EXPECT_NEAR(g.centre_y_slo_mm, b0.start_y_mm - ph.truth.centre_y_mm - p.grid_hint_dy_mm, 1e-9);
    // Central subfield mean thickness lies between CFT and the rim height.
    EXPECT_GT(g.central_thickness_mm, ph.truth.cft_mm);
    EXPECT_LT(g.central_thickness_mm, ph.truth.rim_height_mm);
}

TEST(MaculaPhantom, WrittenFileReadsBack) {
    MaculaPhantomParams p = small(MaculaFamily::kScheibe, io::Laterality::kOS);
    p.size_x = 64;
    p.num_bscans = 7;
    p.pixels = true;
    p.missing_fraction = 0.05;
    p.noise_um = 1.0;
    const MaculaPhantom ph = make_macula_phantom(p);
    const test::TempDir dir;
    const std::string path = (dir / "m.vol").string();
    io::write_vol_file(ph.scan, path);
    std::ifstream in(path, std::ios::binary);
    const auto size = std::filesystem::file_size(path);
    const io::Scan r = io::read_vol(in, size, path, io::ReadOptions{true});
    EXPECT_EQ(r.meta.laterality, io::Laterality::kOS);
    EXPECT_EQ(r.meta.pattern, io::ScanPattern::kVolume);
    EXPECT_EQ(r.meta.size_x, 64);
    EXPECT_EQ(r.meta.distance_mm, ph.scan.meta.distance_mm);
    ASSERT_EQ(r.num_bscans(), 7);
    ASSERT_EQ(r.grids.size(), 1U);
    EXPECT_EQ(r.grids[0].centre_x_slo_mm, ph.scan.grids[0].centre_x_slo_mm);
    EXPECT_EQ(r.slo, ph.scan.slo);
    for (std::size_t b = 0; b < 7; ++b) {
        EXPECT_EQ(r.bscans[b].pixels, ph.scan.bscans[b].pixels);
        EXPECT_EQ(r.bscans[b].start_y_mm, ph.scan.bscans[b].start_y_mm);
        for (int k = 0; k < 2; ++k) {
            for (int a = 0; a < 64; ++a) {
                const float u = r.depth_px(k, static_cast<int>(b), a);
                const float v = ph.scan.depth_px(k, static_cast<int>(b), a);
                EXPECT_TRUE((std::isnan(u) && std::isnan(v)) || u == v);
            }
        }
    }
}

TEST(MaculaPhantom, ValidateNamesTheBadField) {
    MaculaPhantomParams p;
    p.missing_fraction = 0.9;
    try {
        p.validate();
        FAIL() << "accepted";
    } catch (const UsageError& e) {
        EXPECT_NE(std::string(e.what()).find("missing_fraction"), std::string::npos);
    }
    MaculaTruthOptions o;
    o.num_half_lines = 23;
    EXPECT_THROW(o.validate(), UsageError);
    // A retina that does not fit the image depth is refused, not clipped.
    MaculaPhantomParams q = small(MaculaFamily::kBezier);
    q.size_z = 128;
    EXPECT_THROW((void)make_macula_phantom(q), UsageError);
}

TEST(PhantomMaculaCli, WritesScanAndTruth) {
    const test::TempDir dir;
    const std::string vol = (dir / "m.vol").string();
    const auto r = test::run_octshape("phantom macula --bscans 9 --ascans 96 --no-pixels "
                                      "--family scheibe --eye OS --seed 3 -o '" +
                                      vol + "'");
    ASSERT_EQ(r.exit_code, 0) << r.err;
    ASSERT_TRUE(std::filesystem::exists(vol));
    std::ifstream tj((dir / "m.truth.json").string());
    const auto j = nlohmann::json::parse(tj);
    EXPECT_EQ(j["generator"]["family"], "scheibe");
    EXPECT_EQ(j["generator"]["eye"], "OS");
    EXPECT_EQ(j["generator"]["bscans"], 9);
    EXPECT_EQ(j["half_lines"].size(), 24U);
    MaculaPhantomParams p;
    p.family = MaculaFamily::kScheibe;
    p.eye = io::Laterality::kOS;
    p.num_bscans = 9;
    p.size_x = 96;
    const MaculaTruth t = macula_truth(p);
    EXPECT_DOUBLE_EQ(j["parameters"]["rim_volume_mm3"].get<double>(), t.rim_volume_mm3);
    std::ifstream in(vol, std::ios::binary);
    const io::Scan s = io::read_vol(in, std::filesystem::file_size(vol), vol);
    EXPECT_EQ(s.num_bscans(), 9);
    EXPECT_EQ(s.meta.laterality, io::Laterality::kOS);

    EXPECT_EQ(test::run_octshape("phantom macula --missing 0.9 -o '" + vol + "'").exit_code, 64);
    EXPECT_EQ(test::run_octshape("phantom macula -o '" + (dir / "m.txt").string() + "'").exit_code,
              64);
    EXPECT_FALSE(std::filesystem::exists(dir / "m.txt"));
}

// sample_scans/README.md promises that its command reproduces the sample bit for bit.
TEST(PhantomMaculaCli, SampleLineScanIsReproducedBitForBit) {
    const test::TempDir dir;
    const std::string vol = (dir / "l.vol").string();
    const auto r = test::run_octshape(
        "phantom macula --pattern line --family bezier --eye OD --fovea-dx 0.03 --seed 3 -o '" +
        vol + "'");
    ASSERT_EQ(r.exit_code, 0) << r.err;
    auto bytes = [](const std::filesystem::path& path) {
        std::string text(std::filesystem::file_size(path), '\0');
        std::ifstream in(path, std::ios::binary);
        in.read(text.data(), static_cast<std::streamsize>(text.size()));
        return text;
    };
    const auto sample = test::source_dir() / "sample_scans";
    EXPECT_TRUE(bytes(vol) == bytes(sample / "macula_line_od.vol"));
    EXPECT_EQ(bytes(dir / "l.truth.json"), bytes(sample / "macula_line_od.truth.json"));
}

}  // namespace
}  // namespace octshape::retina
