// The stages of the level-set ILM (libretina/onh/src/levelset_stages.h) that the phantom tests
// of levelset_test.cpp pin only through the whole pipeline: each against a value worked out
// by hand from its definition.

#include "../../libretina/onh/src/levelset_stages.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <limits>
#include <vector>

#include "octshape/error.h"
#include "octshape/retina/phantom_onh.h"

namespace octshape::retina::levelset_detail {
namespace {

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();

DeviceIlm flat_ilm(int nb, int na, int nz, float depth) {
    DeviceIlm d;
    d.nb = nb;
    d.na = na;
    d.nz = nz;
    d.h = {0.01, 0.03, 0.004};
    d.ilm.assign(static_cast<std::size_t>(nb * na), depth);
    d.valid.assign(static_cast<std::size_t>(nb * na), 1);
    return d;
}

TEST(LevelSetStages, FillMissingInterpolatesAlongBscansAndCopiesTheNearestBscan) {
    // 4 B-scans × 5 A-scans; B-scan 1 and 3 have no value.
    std::vector<float> g{kNaN, 2.0F, kNaN, kNaN, 8.0F,  // interior gap and leading gap
                         kNaN, kNaN, kNaN, kNaN, kNaN,  // copies B-scan 0 or 2: tie → 0
                         1.0F, 1.0F, 1.0F, 1.0F, 1.0F,  //
                         kNaN, kNaN, kNaN, kNaN, kNaN};  // nearest: B-scan 2
    ASSERT_TRUE(fill_missing(g, 4, 5));
    const std::vector<float> row0{2.0F, 2.0F, 4.0F, 6.0F, 8.0F};
    for (int a = 0; a < 5; ++a) {
        EXPECT_FLOAT_EQ(g[static_cast<std::size_t>(a)], row0[static_cast<std::size_t>(a)]) << a;
        EXPECT_FLOAT_EQ(g[static_cast<std::size_t>(5 + a)], row0[static_cast<std::size_t>(a)]) << a;
        EXPECT_FLOAT_EQ(g[static_cast<std::size_t>(15 + a)], 1.0F) << a;
    }
    std::vector<float> none(6, kNaN);
    EXPECT_FALSE(fill_missing(none, 2, 3));
}

TEST(LevelSetStages, DepthWindowsSpanTheBoxOfIlmDepthsWidenedByTheMargin) {
    // ILM at row 50 everywhere but row 80 at (b, a) = (2, 5); lateral radius 0.025 mm =
    // 2 A-scans (0.01 mm) and 0 B-scans (0.03 mm): the deep column widens a = 3..7 of B-scan 2.
    DeviceIlm d = flat_ilm(5, 11, 200, 50.0F);
    d.ilm[2 * 11 + 5] = 80.0F;
    LevelSetParams p;
    p.lateral_radius_mm = 0.025;
    p.margin_mm = 0.018;  // 4.5 rows
    const Windows w = depth_windows(d, p);
    std::int64_t off = 0;
    for (int b = 0; b < 5; ++b) {
        for (int a = 0; a < 11; ++a) {
            const auto c = static_cast<std::size_t>(w.column(b, a));
            const bool deep = b == 2 && a >= 3 && a <= 7;
            EXPECT_EQ(w.lo[c], 45) << b << "," << a;  // floor(50 − 4.5)
            // ceil(max + 4.5) + 1 exclusive: 56 (flat), 86 (deep)
            EXPECT_EQ(w.lo[c] + w.len[c], deep ? 86 : 56) << b << "," << a;
            EXPECT_EQ(w.offset[c], off);
            off += w.len[c];
        }
    }
    EXPECT_EQ(w.size, off);
    EXPECT_EQ(w.offset.back(), off);
}

TEST(LevelSetStages, DepthWindowsAreClampedToTheRows) {
    const DeviceIlm d = flat_ilm(3, 4, 20, 1.0F);
    LevelSetParams p;
    p.margin_mm = 0.2;  // 50 rows: more than the scan holds
    const Windows w = depth_windows(d, p);
    for (std::size_t c = 0; c < w.lo.size(); ++c) {
        EXPECT_EQ(w.lo[c], 0);
        EXPECT_EQ(w.len[c], 20);
    }
}

TEST(LevelSetStages, BinomialPassKeepsConstantsAndSpreadsADeltaAsTheKernel) {
    const int rows = 9, na = 9;
    std::vector<float> buf(static_cast<std::size_t>(rows * na), 3.0F), tmp(buf.size());
    binomial_pass(buf, tmp, rows, na);
    for (const float v : buf) EXPECT_FLOAT_EQ(v, 3.0F);
    std::fill(buf.begin(), buf.end(), 0.0F);
    buf[4 * na + 4] = 256.0F;
    binomial_pass(buf, tmp, rows, na);
    const float k[5] = {1, 4, 6, 4, 1};  // × 256 / 16² = the outer product of [1 4 6 4 1]
    for (int r = 0; r < rows; ++r) {
        for (int a = 0; a < na; ++a) {
            const bool in = std::abs(r - 4) <= 2 && std::abs(a - 4) <= 2;
            const float want = in ? k[r - 2] * k[a - 2] : 0.0F;
            EXPECT_FLOAT_EQ(buf[static_cast<std::size_t>(r * na + a)], want) << r << "," << a;
        }
    }
}

// Below 1 px the x kernel is [q, 1-2q, q] twice (q = sigma^2 / 4): it keeps constants and
// spreads a delta with variance sigma^2 along x; the depth pass is the binomial's.
TEST(LevelSetStages, NarrowBinomialPassHasTheAskedVarianceAlongX) {
    const int rows = 9, na = 9;
    std::vector<float> buf(static_cast<std::size_t>(rows * na), 3.0F), tmp(buf.size());
    binomial_pass(buf, tmp, rows, na, 0.5);
    for (const float v : buf) EXPECT_FLOAT_EQ(v, 3.0F);
    std::fill(buf.begin(), buf.end(), 0.0F);
    buf[4 * na + 4] = 1.0F;
    binomial_pass(buf, tmp, rows, na, 0.5);
    double sum = 0.0, var = 0.0;
    for (int a = 0; a < na; ++a) {
        const double v = buf[static_cast<std::size_t>(4 * na + a)] * 16.0 / 6.0;  // depth tap 6/16
        sum += v;
        var += v * (a - 4) * (a - 4);
    }
    EXPECT_NEAR(sum, 1.0, 1e-6);
    EXPECT_NEAR(var, 0.25, 1e-6);
    EXPECT_FLOAT_EQ(buf[static_cast<std::size_t>(4 * na + 2)], 1.0F / 256.0F * 6.0F / 16.0F);  // q^2
    EXPECT_FLOAT_EQ(buf[static_cast<std::size_t>(2 * na + 4)] / buf[static_cast<std::size_t>(4 * na + 4)],
                    1.0F / 6.0F);  // depth: the binomial's 1/16 against 6/16
}

TEST(LevelSetStages, DespeckleStoresTheFourthRootOnTheWindowsAndMarksInvalidColumns) {
    DeviceIlm d = flat_ilm(2, 3, 10, 4.0F);
    io::Scan scan;
    scan.bscans.resize(2);
    for (int b = 0; b < 2; ++b) {
        auto& px = scan.bscans[static_cast<std::size_t>(b)].pixels;
        px.resize(30);
        for (int r = 0; r < 10; ++r) {
            for (int a = 0; a < 3; ++a) px[static_cast<std::size_t>(r * 3 + a)] = static_cast<float>(r * r * r * r);
        }
    }
    scan.bscans[1].pixels[5 * 3 + 2] = 2e30F;  // B-scan 1, row 5, A-scan 2: invalid
    LevelSetParams p;
    p.margin_mm = 0.006;  // 1.5 rows: windows [2, 7)
    const Windows w = depth_windows(d, p);
    const std::vector<float> img = despeckle(scan, w, 0, LevelSetParams{}.despeckle_max_sigma_x_mm, d);
    for (int b = 0; b < 2; ++b) {
        for (int a = 0; a < 3; ++a) {
            const auto c = static_cast<std::size_t>(w.column(b, a));
            ASSERT_EQ(w.lo[c], 2);
            ASSERT_EQ(w.len[c], 5);
            for (int r = 0; r < 5; ++r) {
                const bool bad = b == 1 && a == 2 && r + 2 == 5;
                EXPECT_FLOAT_EQ(img[static_cast<std::size_t>(w.offset[c] + r)], bad ? 0.0F : static_cast<float>(r + 2));
            }
            EXPECT_EQ(d.valid[c], (b == 1 && a == 2) ? 0 : 1);
        }
    }
}

TEST(LevelSetStages, InitialPhiIsTheSignedVerticalDistanceToTheDeviceIlm) {
    DeviceIlm d = flat_ilm(2, 2, 40, 20.25F);
    LevelSetParams p;
    const Windows w = depth_windows(d, p);
    const std::vector<float> phi = initial_phi(w, d);
    for (std::size_t c = 0; c < w.lo.size(); ++c) {
        for (int r = 0; r < w.len[c]; ++r) {
            const double want = (20.25 - (w.lo[c] + r)) * d.h.hz;  // > 0 above (vitreous)
            EXPECT_FLOAT_EQ(phi[static_cast<std::size_t>(w.offset[c] + r)], static_cast<float>(want));
        }
    }
}

// Leaks (docs/algorithms/levelset.md "Leaks"): a flat ILM at row 20.25 (hz 4 um; leak depth
// 16 um = 4 rows). B-scan 1 holds a leak 5 A-scans wide whose top crossing is 10 rows deep, a
// 2-A-scan dip of the same depth (shorter than the 3-A-scan run: a lip's tip) and a device-line
// spike of 3 A-scans 12 rows up into the vitreous (the level set is right there; the 9-A-scan
// median drops the spike). Only the leak, widened by 2 A-scans, falls back to phi0; B-scan 0 is
// left alone.
TEST(LevelSetStages, LeaksFallBackToTheDeviceIlmAndLipTipsAndSpikesDoNot) {
    DeviceIlm d = flat_ilm(2, 40, 60, 20.25F);
    const int na = 40;
    for (int a = 30; a < 33; ++a) d.ilm[static_cast<std::size_t>(na + a)] = 8.25F;  // spike
    LevelSetParams p;
    const Windows w = depth_windows(d, p);
    const DeviceIlm flat = flat_ilm(2, 40, 60, 20.25F);
    std::vector<float> phi = initial_phi(w, flat);  // the true surface, spike or not
    auto top_at = [&](int b, int a, double row) {
        const auto c = static_cast<std::size_t>(w.column(b, a));
        for (int r = 0; r < w.len[c]; ++r) {
            phi[static_cast<std::size_t>(w.offset[c] + r)] =
                static_cast<float>((row - (w.lo[c] + r)) * d.h.hz);
        }
    };
    for (int a = 10; a < 15; ++a) top_at(1, a, 30.25);  // the leak
    for (int a = 20; a < 22; ++a) top_at(1, a, 30.25);  // the dip
    const std::vector<float> before = phi;
    std::vector<int> bscans;
    const std::int64_t n = fall_back_leaks(w, phi, d, p.leak_depth_mm, bscans);
    EXPECT_EQ(n, 9);  // A-scans 8-16
    EXPECT_EQ(bscans, std::vector<int>{1});
    for (int b = 0; b < 2; ++b) {
        for (int a = 0; a < na; ++a) {
            const auto c = static_cast<std::size_t>(w.column(b, a));
            const bool fell = b == 1 && a >= 8 && a <= 16;
            for (int r = 0; r < w.len[c]; ++r) {
                const auto i = static_cast<std::size_t>(w.offset[c] + r);
                if (fell) {
                    EXPECT_FLOAT_EQ(phi[i], static_cast<float>((20.25 - (w.lo[c] + r)) * d.h.hz))
                        << b << " " << a;
                } else {
                    EXPECT_EQ(phi[i], before[i]) << b << " " << a;
                }
            }
        }
    }
}

// Shadowed tissue (docs/algorithms/levelset.md "Leaks"): a flat ILM at row 20.25 (hz 4 um;
// hidden = more than 16 um = 4 rows below it, rows >= 25), vitreous 0.1 above it, tissue 0.6
// below (c_tissue): the threshold is 0.1 + 0.5 / 4 = 0.225. In B-scan 1, rows 26-33 are vitreous
// (phi > 0) in a dark cavity (A-scans 5-12, 0.07: a shadowed cavity is darker, never brighter,
// than the vitreous), its wall's 2-A-scan blur (13-14, 0.35: thinner than the 3 x 3 block) and
// a leak into shadowed tissue (20-27, 0.35); a bright floater lies in the open vitreous (rows
// 10-14, A-scans 30-35, 0.5). Only the leak is cut (phi <= 0 there, its 8 columns counted);
// the cavity, the blur, the floater, the tissue around the leak and B-scan 0 keep their phi.
TEST(LevelSetStages, ShadowedTissueIsCutAndCavitiesWallBlurAndFloatersAreNot) {
    const int na = 40;
    const DeviceIlm d = flat_ilm(2, na, 60, 20.25F);
    LevelSetParams p;
    const Windows w = depth_windows(d, p);
    std::vector<float> phi = initial_phi(w, d);
    std::vector<float> image(phi.size());
    for (std::size_t c = 0; c < w.lo.size(); ++c) {
        for (int r = 0; r < w.len[c]; ++r) {
            image[static_cast<std::size_t>(w.offset[c] + r)] = w.lo[c] + r < 20.25 ? 0.1F : 0.6F;
        }
    }
    auto set = [&](int a0, int a1, int r0, int r1, float value, bool vitreous) {
        for (int a = a0; a <= a1; ++a) {
            const auto c = static_cast<std::size_t>(w.column(1, a));
            for (int d_row = r0; d_row <= r1; ++d_row) {
                const auto i = static_cast<std::size_t>(w.offset[c] + (d_row - w.lo[c]));
                image[i] = value;
                if (vitreous) phi[i] = static_cast<float>(d.h.hz);
            }
        }
    };
    set(5, 12, 26, 33, 0.07F, true);   // the cavity
    set(13, 14, 26, 33, 0.35F, true);  // its wall's blur
    set(20, 27, 26, 33, 0.35F, true);  // the leak
    set(30, 35, 10, 14, 0.5F, false);  // the floater
    ASSERT_LE(w.lo[0], 10);
    ASSERT_GE(w.lo[0] + w.len[0], 34);
    const std::vector<float> before = phi;
    std::vector<int> bscans;
    const std::int64_t n = cut_shadowed_tissue(w, phi, image, d, 0.6, p.leak_depth_mm, bscans);
    EXPECT_EQ(n, 8);
    EXPECT_EQ(bscans, std::vector<int>{1});
    for (int b = 0; b < 2; ++b) {
        for (int a = 0; a < na; ++a) {
            const auto c = static_cast<std::size_t>(w.column(b, a));
            for (int r = 0; r < w.len[c]; ++r) {
                const auto i = static_cast<std::size_t>(w.offset[c] + r);
                const int row = w.lo[c] + r;
                const bool leak = b == 1 && a >= 20 && a <= 27 && row >= 26 && row <= 33;
                if (leak) {
                    EXPECT_LE(phi[i], 0.0F) << a << " " << row;
                } else {
                    EXPECT_EQ(phi[i], before[i]) << b << " " << a << " " << row;
                }
            }
        }
    }
}

// φ of a flat interface half-way between rows 20 and 21 on every column.
struct FlatCase {
    DeviceIlm ilm;
    Windows w;
    std::vector<float> phi;
};
FlatCase flat_case(int nb, int na) {
    FlatCase f{flat_ilm(nb, na, 60, 20.5F), {}, {}};
    f.w = depth_windows(f.ilm, LevelSetParams{});
    f.phi = initial_phi(f.w, f.ilm);
    return f;
}

TEST(LevelSetStages, SurfaceOfAFlatInterfaceIsOneGridAcrossTheSlabs) {
    // 7 B-scans in slabs of 3 (sharing their last B-scan): slabs [0,2], [2,4], [4,6].
    const int nb = 7, na = 6;
    const FlatCase f = flat_case(nb, na);
    const Surface s = surface(f.w, f.phi, f.ilm.h, 3);
    // One point per column (the shared B-scan planes merged exactly), two triangles per cell.
    EXPECT_EQ(s.V.rows(), nb * na);
    EXPECT_EQ(s.F.rows(), 2 * (nb - 1) * (na - 1));
    for (Eigen::Index i = 0; i < s.V.rows(); ++i) {
        // φ is ±hz/2 on the rows either side: the crossing is exactly half-way; VTK's float
        // points round 0.082 mm to ~7e-9 mm.
        EXPECT_NEAR(s.V(i, 2), -20.5 * f.ilm.h.hz, 1e-8) << i;
    }
}

TEST(LevelSetStages, CleanUpClipsInvalidColumnsKeepsTheLargestPartAndOrientsUp) {
    const int nb = 9, na = 9;
    FlatCase f = flat_case(nb, na);
    Surface s = surface(f.w, f.phi, f.ilm.h, 16);
    // Reverse the faces so that the orientation step has something to do.
    s.F.col(1).swap(s.F.col(2));
    // The invalid columns a = 3, 4 cut the grid in two. Each cell [a, a + 1] holds two
    // triangles whose centroids lie at x/hx = a + 1/3 and a + 2/3 (either diagonal); a face is
    // clipped when that rounds to 3 or 4: 2.67, 3.33, 3.67, 4.33 — four per row of cells.
    std::vector<std::uint8_t> valid(static_cast<std::size_t>(nb * na), 1);
    for (int b = 0; b < nb; ++b) {
        valid[static_cast<std::size_t>(b * na + 3)] = 0;
        valid[static_cast<std::size_t>(b * na + 4)] = 0;
    }
    const CleanUp c = clean_up(s, valid, nb, na, f.ilm.h);
    EXPECT_EQ(c.clipped_faces, 4 * (nb - 1));
    // Left: cells 0, 1 and the face at 2.33 (vertices x ≤ 3); right: the face at 4.67 and
    // cells 5, 6, 7 (vertices x ≥ 4): disjoint, the right one larger (7 faces per row vs 5).
    EXPECT_EQ(c.components, 2);
    EXPECT_EQ(s.F.rows(), 7 * (nb - 1));
    // VTK keeps the points in float: 0.04 mm to ~4e-9 mm.
    EXPECT_NEAR(s.V.col(0).minCoeff(), 4.0 * f.ilm.h.hx, 1e-8);
    const mesh::FaceGeometry g = mesh::face_geometry(s.V, s.F);
    for (Eigen::Index k = 0; k < s.F.rows(); ++k) EXPECT_GT(g.normals(k, 2), 0.99) << k;
}

TEST(LevelSetStages, CleanUpWithNothingValidIsAnAnalysisError) {
    FlatCase f = flat_case(4, 4);
    Surface s = surface(f.w, f.phi, f.ilm.h, 16);
    const std::vector<std::uint8_t> none(16, 0);
    EXPECT_THROW((void)clean_up(s, none, 4, 4, f.ilm.h), AnalysisError);
}

TEST(LevelSetStages, SmoothOffKeepsThePositions) {
    FlatCase f = flat_case(4, 5);
    Surface s = surface(f.w, f.phi, f.ilm.h, 16);
    const mesh::Vertices V = s.V;
    const mesh::Faces F = s.F;
    LevelSetParams p;
    p.smooth = false;
    LevelSetResult res;
    smooth(std::move(s), p, res);
    EXPECT_TRUE(res.V == V);
    EXPECT_TRUE(res.V_raw == V);
    EXPECT_TRUE(res.F == F);
    EXPECT_EQ(res.rofi_iterations, 0);
}

// The cavity under the rim lip, in one B-scan through the overhanging disc: per A-scan that
// meets the true ILM three times (lip top, lip underside, the wall or floor below), the
// vertical length of the vitreous under the first tissue row, from the evolved φ (crossings
// by linear interpolation, as marching cubes and marching squares place them) against the
// phantom's own crossings. Returns the mean excess per hidden crossing (two per A-scan), px.
struct CavityExcess {
    double mean_px = 0.0;
    int ascans = 0;
};
CavityExcess cavity_excess(const io::Scan& scan, const OnhPhantomGeometry& g, int b,
                           const LevelSetParams& p) {
    const int na = scan.meta.size_x;
    const double hz = scan.meta.scale_z_mm;
    DeviceIlm ilm = device_ilm_rows(scan, b, 1, {scan.meta.scale_x_mm, std::numeric_limits<double>::infinity(), hz});
    EXPECT_TRUE(fill_missing(ilm.ilm, 1, na));
    const Windows w = depth_windows(ilm, p);
    const std::vector<float> image = despeckle(scan, w, p.despeckle_passes, p.despeckle_max_sigma_x_mm, ilm, b);
    std::vector<float> phi = initial_phi(w, ilm);
    LevelSetResult res;
    evolve(w, phi, image, p, ilm.h, res);
    EXPECT_TRUE(res.converged);
    double sum = 0.0;
    CavityExcess out;
    for (int a = 0; a < na; ++a) {
        const std::vector<double> h = g.ilm_heights(a * scan.meta.scale_x_mm, b * scan.meta.distance_mm);
        if (h.size() < 3) continue;
        double truth = 0.0;  // mm of vitreous under the first crossing
        for (std::size_t k = 1; k + 1 < h.size(); k += 2) truth += h[k] - h[k + 1];
        // Crossings of φ down the column (rows above the window vitreous, below it tissue).
        const int lo = w.lo[static_cast<std::size_t>(a)];
        const int len = w.len[static_cast<std::size_t>(a)];
        const float* f = phi.data() + w.offset[static_cast<std::size_t>(a)];
        std::vector<double> cross;
        if (f[0] <= 0.0F) cross.push_back(lo);
        for (int d = 0; d + 1 < len; ++d) {
            if ((f[d] > 0.0F) != (f[d + 1] > 0.0F)) {
                cross.push_back(lo + d + static_cast<double>(f[d]) / (static_cast<double>(f[d]) - f[d + 1]));
            }
        }
        if (cross.size() % 2 == 0) cross.push_back(lo + len - 1);  // vitreous to the bottom
        double cavity = 0.0;  // px
        for (std::size_t k = 1; k + 1 < cross.size(); k += 2) cavity += cross[k + 1] - cross[k];
        sum += cavity - truth / hz;
        ++out.ascans;
    }
    out.mean_px = out.ascans > 0 ? sum / (2.0 * out.ascans) : 0.0;
    return out;
}

// Under the lip the tissue is dimmer than at the open surfaces that set the band means
// (the nerve fibres' reflectance decays below the first crossing), so one global decision
// level lies inside that tissue and the cavity comes out too large: +0.19 to +0.30 px per
// hidden crossing on this B-scan over speckle seeds 1-6 with hidden_local_level off. With each
// hidden voxel's own level (the default) −0.10 to +0.08 px (SD 0.07 px). Asserted: the cavity
// is not larger than the truth by more than 0.15 px per crossing (2 SD of the speckle draw),
// the local level takes at least 0.1 px off the global one's excess (measured 0.20-0.31),
// and the cavity is not smaller by more than a pixel (the open surfaces' own offset towards
// the vitreous is 0.3-0.7 px, docs/algorithms/levelset.md "Where the zero level settles").
// One B-scan of the full-size overhang phantom (the middle B-scan of a 5-B-scan volume,
// through the disc), evolved as a radial line is (nb = 1).
TEST(LevelSetStages, CavityUnderTheLipIsNotTooLarge) {
    OnhPhantomParams pp = onh_phantom_preset(OnhShape::kOverhang);
    pp.num_bscans = 5;
    const io::Scan scan = render_onh_scan(pp);
    const OnhPhantomGeometry g(pp);
    LevelSetParams p;
    const CavityExcess now = cavity_excess(scan, g, 2, p);
    p.hidden_local_level = false;
    const CavityExcess global = cavity_excess(scan, g, 2, p);
    std::printf("cavity under the lip, %d A-scans: excess per hidden crossing %.3f px (global level %.3f px)\n",
                now.ascans, now.mean_px, global.mean_px);
    ASSERT_GE(now.ascans, 20);
    ASSERT_EQ(global.ascans, now.ascans);
    EXPECT_LE(now.mean_px, 0.15);
    EXPECT_GE(global.mean_px - now.mean_px, 0.1);
    EXPECT_GE(now.mean_px, -1.0);
}

// One radial B-scan's evolution (as onh_radial_levelset.cpp runs it): the region means and
// whether it converged.
LevelSetResult evolve_radial_bscan(const io::Scan& scan, double line_length_mm, int k,
                                   const LevelSetParams& p) {
    const int na = scan.meta.size_x;
    const double hz = scan.meta.scale_z_mm;
    DeviceIlm ilm = device_ilm_rows(scan, k, 1, {line_length_mm / (na - 1), std::numeric_limits<double>::infinity(), hz});
    EXPECT_TRUE(fill_missing(ilm.ilm, 1, na));
    const Windows w = depth_windows(ilm, p);
    const std::vector<float> image = despeckle(scan, w, p.despeckle_passes, p.despeckle_max_sigma_x_mm, ilm, k);
    std::vector<float> phi = initial_phi(w, ilm);
    LevelSetResult res;
    evolve(w, phi, image, p, ilm.h, res, p.open_vitreous_mean ? ilm.ilm.data() : nullptr);
    return res;
}

// A front that runs into a vessel's shadow (tissue 0.32-0.40 against a decision level of
// ~0.38) used to count the shadowed tissue it took among the vitreous: the vitreous mean rose
// (0.186 -> 0.238 on this B-scan), the decision level with it, and more of the shadow fell
// below it — the B-scan did not converge in 400 + 100 iterations (the refinement under the lip
// at its cap, about a local level raised by the same leak; docs/algorithms/levelset.md
// "Vitreous mean"). The overhanging disc, 4 radial lines with vessel shadows and device-line
// faults: line 3 (135 deg) leaks, line 0 does not. Asserted: line 3 converges, and its vitreous
// mean is line 0's within 0.01 (the open vitreous is the same on every line: lines 0-2 measured
// 0.182-0.187); with every vitreous band voxel counted (open_vitreous_mean off) it is more
// than 0.03 above (measured +0.05), so the set-up does reproduce the leak.
TEST(LevelSetStages, ShadowLeakDoesNotRaiseTheVitreousMean) {
    OnhPhantomParams pp = onh_phantom_preset(OnhShape::kOverhang);
    pp.radial = true;
    pp.radial_lines = 4;
    pp.artefacts.vessel_shadows = true;
    pp.artefacts.segmentation_faults = true;
    const io::Scan scan = render_onh_scan(pp);
    LevelSetParams p;
    const LevelSetResult clean = evolve_radial_bscan(scan, pp.line_length_mm, 0, p);
    const LevelSetResult shadow = evolve_radial_bscan(scan, pp.line_length_mm, 3, p);
    p.open_vitreous_mean = false;
    const LevelSetResult before = evolve_radial_bscan(scan, pp.line_length_mm, 3, p);
    std::printf("vitreous mean: line 0 %.3f, line 3 %.3f (all vitreous counted %.3f); line 3 %d iterations (%d)\n",
                clean.c_vitreous, shadow.c_vitreous, before.c_vitreous, shadow.iterations, before.iterations);
    EXPECT_TRUE(shadow.converged);
    EXPECT_NEAR(shadow.c_vitreous, clean.c_vitreous, 0.01);
    EXPECT_GT(before.c_vitreous - clean.c_vitreous, 0.03);
}

// The band means (LevelSetParams::RegionMeans::kBand) see only the image near the surface.
// A plane at slope 1.5 along the B-scans (90 um apart), flat in x, over an asymmetric edge
// (vitreous 0.1; tissue 0.8 for 4 px under the edge, 0.3 below; the edge pixel mixed by its
// covered fraction), the image given directly (display units). Layer 0 of the band holds
// every voxel with a 6-neighbour of the other sign, so along a coarse y it spans slope x
// spacing in depth (135 um here): clear vitreous and dim tissue far from the edge, which
// pulled both means down, the more the coarser the B-scans (docs/algorithms/onh.md "The level
// set's cup-volume deficit"). The means now hold only band voxels with |phi| <= (W + 1) in-plane
// spacings (34 um; a layer-0 voxel reached along y has |phi| = its distance to the crossing
// along y, 1/1.5 of its depth below or above the plane). Asserted: darkening the image farther
// than 100 um (26 px) in depth from the edge, where no counted voxel lies (34 um x 1.5 = 51 um,
// and the front settles within 2 px of the edge), leaves the decision level exactly as it was
// (measured 0.2729 both; before the change 0.2149 -> 0.0676).
double sloped_plane_level(double far_value) {
    const int nb = 12, na = 6, nz = 700;
    const double hx = 0.0113, dy = 0.09, hz = 0.00387, slope = 1.5;
    DeviceIlm d;
    d.nb = nb;
    d.na = na;
    d.nz = nz;
    d.h = {hx, dy, hz};
    d.ilm.resize(static_cast<std::size_t>(nb * na));
    d.valid.assign(static_cast<std::size_t>(nb * na), 1);
    auto edge = [&](int b) { return 60.0 + 0.3 + slope * b * dy / hz; };  // px, deeper with b
    for (int b = 0; b < nb; ++b) {
        for (int a = 0; a < na; ++a) d.ilm[static_cast<std::size_t>(b * na + a)] = static_cast<float>(edge(b));
    }
    LevelSetParams p;
    const Windows w = depth_windows(d, p);
    std::vector<float> image(static_cast<std::size_t>(w.size), 0.0F);
    for (int b = 0; b < nb; ++b) {
        for (int a = 0; a < na; ++a) {
            const auto c = static_cast<std::size_t>(w.column(b, a));
            for (int r = 0; r < w.len[c]; ++r) {
                const double t = w.lo[c] + r - edge(b);  // px below the edge (pixel centre)
                // Pixel r covers [t - 1/2, t + 1/2]: its tissue fraction mixes the two values.
                const double f = std::clamp(t + 0.5, 0.0, 1.0);
                const double tissue = t < 4.0 ? 0.8 : 0.3;
                double v = (1.0 - f) * 0.1 + f * tissue;
                if (far_value >= 0.0 && std::abs(t) * hz > 0.1) v = far_value;
                image[static_cast<std::size_t>(w.offset[c] + r)] = static_cast<float>(v);
            }
        }
    }
    std::vector<float> phi = initial_phi(w, d);
    LevelSetResult res;
    evolve(w, phi, image, p, d.h, res);
    EXPECT_TRUE(res.converged);
    return 0.5 * (res.c_vitreous + res.c_tissue);
}

TEST(LevelSetStages, BandMeansSeeOnlyTheImageNearTheSurface) {
    // Far from the edge: the values the profile has there (vitreous above, dim tissue below),
    // then black.
    const double as_is = sloped_plane_level(-1.0);
    const double dark = sloped_plane_level(0.0);
    std::printf("decision level of a plane at slope 1.5 along y, 90 um between B-scans: %.4f, far image "
                "black %.4f\n", as_is, dark);
    EXPECT_EQ(as_is, dark);
}

}  // namespace
}  // namespace octshape::retina::levelset_detail
