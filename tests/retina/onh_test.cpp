// The ONH analysis (docs/algorithms/onh.md) against closed forms and the ONH phantoms' truth, with
// the device ILM as a graph mesh. The truth is computed from the phantom's generating functions
// (phantom_onh.h), never from sampled lines or pixels.
//
// Sampling of the full-size phantoms: ScaleX dx = 4.35/384 = 11.3 um, Distance dy = 4.35/144
// = 30.2 um. The error sources and their sizes (docs/algorithms/onh.md, "Accuracy"):
//  * BMO points: each gap end is placed half-way between the last present and the first
//    missing A-scan: uniform error within +-dx/2 (sigma = dx/sqrt(12) = 3.3 um), zero mean.
//    The ellipse fit to ~120 points averages it: axes and centre to ~1 um, area to ~0.2 %.
//  * ILM graph: piecewise-linear (PL) interpolation of the exact device heights at the nodes.
//    Its mean error over a triangle with legs dx, dy is (dx^2 h_xx + dy^2 h_yy + dx dy h_xy)/12,
//    so over a region it is (1/12)(dx^2 + dy^2) times the boundary flux of grad h: for the cup
//    (|grad h| ~ 1.3 at h = 0, perimeter ~ 3 mm) ~ 3e-4 mm3 = 0.2 % of V_cup.
//  * Region membership by face centroid: the faces cut by the ellipse or the disc circle are
//    in or out as a whole: zero-mean errors of ~A_face * h per face (A_face = dx dy / 2 =
//    1.7e-4 mm2, h ~ 0.45 mm, ~700 faces): sigma ~ sqrt(700) * 1.7e-4 * 0.45 / sqrt(12)
//    ~ 6e-4 mm3, 0.1-0.2 % of V_bmo.
//  * RPE: the thin-plate fill reproduces the quadratic BM exactly; the BM depths are float32
//    in the file (~1e-7 mm).
// A 1 % bound on every volume is > 4 sigma + the PL term; the target for the level set
// is 2 %.

#include "octshape/retina/onh.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <map>
#include <numbers>
#include <string>
#include <tuple>

#include "octshape/error.h"
#include "octshape/retina/phantom_onh.h"
#include "onh_mrw_points.h"
#include "slow_test.h"

namespace octshape::retina {
namespace {

constexpr double kPi = std::numbers::pi;

// Splits every triangle into four through its edge midpoints: the same piecewise-linear
// surface with 4x the faces.
IlmSurface refine(const IlmSurface& in) {
    IlmSurface out = in;
    std::map<std::pair<int, int>, int> mid;
    std::vector<Eigen::Vector3d> verts;
    for (Eigen::Index i = 0; i < in.V.rows(); ++i) verts.emplace_back(in.V.row(i));
    auto midpoint = [&](int a, int b) {
        const auto key = std::minmax(a, b);
        const auto it = mid.find(key);
        if (it != mid.end()) return it->second;
        verts.push_back(0.5 *
                        (verts[static_cast<std::size_t>(a)] + verts[static_cast<std::size_t>(b)]));
        const int id = static_cast<int>(verts.size()) - 1;
        mid.emplace(key, id);
        return id;
    };
    std::vector<std::array<int, 3>> tris;
    for (Eigen::Index f = 0; f < in.F.rows(); ++f) {
        const int a = in.F(f, 0);
        const int b = in.F(f, 1);
        const int c = in.F(f, 2);
        const int ab = midpoint(a, b);
        const int bc = midpoint(b, c);
        const int ca = midpoint(c, a);
        tris.push_back({a, ab, ca});
        tris.push_back({ab, b, bc});
        tris.push_back({ca, bc, c});
        tris.push_back({ab, bc, ca});
    }
    out.V.resize(static_cast<Eigen::Index>(verts.size()), 3);
    for (std::size_t i = 0; i < verts.size(); ++i)
        out.V.row(static_cast<Eigen::Index>(i)) = verts[i];
    out.F.resize(static_cast<Eigen::Index>(tris.size()), 3);
    for (std::size_t f = 0; f < tris.size(); ++f) {
        out.F.row(static_cast<Eigen::Index>(f)) << tris[f][0], tris[f][1], tris[f][2];
    }
    out.vertex_filled.clear();
    return out;
}

OnhPhantomParams reduced(OnhShape shape) {
    OnhPhantomParams p = onh_phantom_preset(shape);
    p.num_bscans = 49;
    p.num_ascans = 192;
    return p;
}

TEST(OnhAnalysis, CupVolumeDoesNotDependOnMeshResolution) {
    const io::Scan scan = render_onh_scan(reduced(OnhShape::kCupped));
    const IlmSurface ilm = device_ilm_surface(scan);
    const IlmSurface fine = refine(ilm);
    ASSERT_EQ(fine.F.rows(), 4 * ilm.F.rows());
    OnhParams p;
    p.local_features = false;
    const OnhResult a = analyse_onh(scan, ilm, p);
    const OnhResult b = analyse_onh(scan, fine, p);
    ASSERT_GT(a.cup_volume_mm3, 0.1);
    // The refined mesh is the same PL surface; only the faces cut by h = 0 (or by the ellipse
    // and the disc circle) change: zero-mean differences of ~A_face |grad h| size per face,
    // sqrt(#cut faces) ~ 20 of them: ~1e-4 relative. 0.5 % is a > 10 sigma bound, and 4x
    // below the 2 % an O(h^2) resolution effect of halving the faces' size would show here
    // (this reduced phantom's cup is 1.7 % below truth).
    EXPECT_NEAR(b.cup_volume_mm3, a.cup_volume_mm3, 0.005 * a.cup_volume_mm3);
    EXPECT_NEAR(b.bmo_volume_mm3, a.bmo_volume_mm3, 0.005 * a.bmo_volume_mm3);
    EXPECT_NEAR(b.total_volume_mm3, a.total_volume_mm3, 0.005 * a.total_volume_mm3);
    // Same surface: the top crossing and the closest points are the same to rounding.
    EXPECT_NEAR(b.conht_mm, a.conht_mm, 1e-12);
    EXPECT_NEAR(b.mrw_mean_mm, a.mrw_mean_mm, 1e-12);
    EXPECT_NEAR(b.mrw_area_mm2, a.mrw_area_mm2, 1e-9);
    // The normal tensor of the BMO region is a sum over the same planar pieces.
    EXPECT_NEAR(b.bending_energy, a.bending_energy, 0.005 * a.bending_energy);
}

TEST(OnhAnalysis, FaceOrientationOfTheInputDoesNotMatter) {
    const io::Scan scan = render_onh_scan(reduced(OnhShape::kSwollen));
    const IlmSurface ilm = device_ilm_surface(scan);
    IlmSurface flipped = ilm;
    flipped.F.col(1).swap(flipped.F.col(2));
    OnhParams p;
    p.local_features = false;
    const OnhResult a = analyse_onh(scan, ilm, p);
    const OnhResult b = analyse_onh(scan, flipped, p);
    EXPECT_FALSE(a.ilm_flipped);
    EXPECT_TRUE(b.ilm_flipped);
    EXPECT_DOUBLE_EQ(a.total_volume_mm3, b.total_volume_mm3);
    EXPECT_DOUBLE_EQ(a.bmo_volume_mm3, b.bmo_volume_mm3);
    EXPECT_DOUBLE_EQ(a.bending_energy, b.bending_energy);
    EXPECT_EQ(a.cup_volume_mm3, 0.0);  // the swollen disc has no cup
    EXPECT_FALSE(a.has_cup);
}

// A fold no height field can describe, over a flat RPE at z = 0: the profile in x goes right
// at z = 0.3 to x = 2, back left at z = 0.2 to x = 1 (the underside of a lip: it faces down),
// then right again at z = 0.1 to x = 3; extruded along y in [0, 1]. Vertical lines with
// 1 < x < 2 meet it three times: tissue 0.3 - 0.2 + 0.1 = 0.2. The signed projected areas give
// the tissue volume 0.3 * 1 + 0.2 * 1 + 0.1 * 1 = 0.6; unsigned areas would give 0.8.
TEST(OnhRegions, SignedProjectedAreasMeasureAFoldRight) {
    GridSurface rpe;
    rpe.cols = 31;
    rpe.rows = 11;
    rpe.dx_mm = 0.1;
    rpe.dy_mm = 0.1;
    rpe.z.assign(static_cast<std::size_t>(rpe.cols * rpe.rows), 0.0);
    rpe.filled.assign(rpe.z.size(), 0);
    // Profile vertices (x, z), each extruded to y = 0 and y = 1.
    const std::vector<std::pair<double, double>> prof{{0.0, 0.3}, {2.0, 0.3}, {2.0, 0.2},
                                                      {1.0, 0.2}, {1.0, 0.1}, {3.0, 0.1}};
    mesh::Vertices V(static_cast<Eigen::Index>(2 * prof.size()), 3);
    for (std::size_t i = 0; i < prof.size(); ++i) {
        V.row(static_cast<Eigen::Index>(2 * i)) << prof[i].first, 0.0, prof[i].second;
        V.row(static_cast<Eigen::Index>(2 * i + 1)) << prof[i].first, 1.0, prof[i].second;
    }
    mesh::Faces F(static_cast<Eigen::Index>(2 * (prof.size() - 1)), 3);
    for (int i = 0; i + 1 < static_cast<int>(prof.size()); ++i) {
        const int a0 = 2 * i;
        const int a1 = 2 * i + 1;
        const int b0 = 2 * i + 2;
        const int b1 = 2 * i + 3;
        F.row(2 * i) << a0, b0, b1;
        F.row(2 * i + 1) << a0, b1, a1;
    }
    BmoEllipse everything;  // an ellipse holding the whole strip; the disc holds it too
    everything.centre_mm = Eigen::Vector2d(1.5, 0.5);
    everything.semi_major_mm = 10.0;
    everything.semi_minor_mm = 10.0;
    const OnhRegions m = measure_onh_regions(V, F, rpe, everything, 20.0);
    EXPECT_NEAR(m.bmo_volume_mm3, 0.6, 1e-12);
    EXPECT_NEAR(m.total_volume_mm3, 0.6, 1e-12);
    EXPECT_NEAR(m.annular_volume_mm3, 0.0, 1e-12);
    EXPECT_EQ(m.cup_volume_mm3, 0.0);
    // Lower the RPE by nothing but move the strip below it: a cup of the same volume.
    mesh::Vertices below = V;
    below.col(2) = V.col(2).array() - 0.4;  // heights -0.1, -0.2, -0.3
    const OnhRegions cup = measure_onh_regions(below, F, rpe, everything, 20.0);
    // -(sum A h): 0.1 * 2 - 0.2 * 1 + 0.3 * 2 = 0.6 (the underside counts negatively).
    EXPECT_NEAR(cup.cup_volume_mm3, 0.6, 1e-12);
    EXPECT_EQ(cup.bmo_volume_mm3, 0.0);
    // A face beyond the RPE grid is in no region.
    mesh::Vertices shifted = V;
    shifted.col(0).array() += 1.5;  // the last strip's centroids at x = 3.83 and 4.17 > 3.0
    const OnhRegions out = measure_onh_regions(shifted, F, rpe, everything, 20.0);
    EXPECT_GT(out.faces_outside_rpe, 0);
}

TEST(OnhEnface, EachCellShowsItsTopmostFaceAndNothingWhereNoFaceIs) {
    // RPE grid of 3 x 3 nodes (2 x 2 cells of 1 mm), flat at 0, so a face's height is its z.
    OnhResult r;
    r.rpe.cols = 3;
    r.rpe.rows = 3;
    r.rpe.dx_mm = 1.0;
    r.rpe.dy_mm = 1.0;
    r.rpe.z.assign(9, 0.0);
    // Small flat triangles with their centroids at (cx, cy): two over cell (0, 0), the lower
    // one last (an overhang: the upper one is seen); one over cell (1, 0) below the RPE; one
    // beyond the grid's corner (counted in cell (1, 1)); one without a height over cell (0, 1).
    const std::vector<std::array<double, 4>> faces{{0.4, 0.4, 0.5, 0.5}, {0.5, 0.3, 0.2, 0.2},
                                                   {1.5, 0.5, -0.1, -0.1}, {2.5, 2.5, 0.3, 0.3},
                                                   {0.5, 1.5, 0.4, std::nan("")}};
    r.ilm_V.resize(static_cast<Eigen::Index>(3 * faces.size()), 3);
    r.ilm_F.resize(static_cast<Eigen::Index>(faces.size()), 3);
    r.face_height_mm.resize(static_cast<Eigen::Index>(faces.size()));
    for (int f = 0; f < static_cast<int>(faces.size()); ++f) {
        const auto& [cx, cy, z, h] = faces[static_cast<std::size_t>(f)];
        r.ilm_V.row(3 * f) << cx - 0.1, cy - 0.1, z;
        r.ilm_V.row(3 * f + 1) << cx + 0.2, cy - 0.1, z;
        r.ilm_V.row(3 * f + 2) << cx - 0.1, cy + 0.2, z;
        r.ilm_F.row(f) << 3 * f, 3 * f + 1, 3 * f + 2;
        r.face_height_mm(f) = h;
    }
    const OnhEnfaceGrid g = onh_enface_heights(r);
    ASSERT_EQ(g.cols, 2);
    ASSERT_EQ(g.rows, 2);
    EXPECT_DOUBLE_EQ(g.at(0, 0), 0.5);
    EXPECT_DOUBLE_EQ(g.at(1, 0), -0.1);
    EXPECT_DOUBLE_EQ(g.at(1, 1), 0.3);
    EXPECT_TRUE(std::isnan(g.at(0, 1)));
}

TEST(OnhAnalysis, LeftEyeSectorsAreMirroredAsTheTruthDefinesThem) {
    // A tilted ellipse (30 deg) is far from mirror-symmetric, so a wrong mirroring would move
    // the anatomical angles of the BMO points by up to 2 x 60 deg.
    OnhPhantomParams p = reduced(OnhShape::kCupped);
    p.eye = io::Laterality::kOS;
    p.num_bscans = 73;
    p.bmo_rotation_deg = 30.0;
    OnhTruthOptions coarse;  // accuracy ~1e-9 (docs/phantoms.md): ample for this comparison
    coarse.s_step = 0.04;
    coarse.phi_steps = 180;
    const OnhPhantom ph = make_onh_phantom(p, coarse);
    OnhParams op;
    op.local_features = false;
    const OnhResult r = analyse_onh(ph.scan, device_ilm_surface(ph.scan), op);
    EXPECT_EQ(r.eye, "OS");
    // Ellipse orientation: from the fit (float RotatedRect, ~0.1 deg from the quantised ends).
    EXPECT_NEAR(r.ellipse.orientation_deg, ph.truth.bmo_orientation_deg, 0.5);
    EXPECT_NEAR(r.bmo_orientation_anatomical_deg, ph.truth.bmo_orientation_anatomical_deg, 0.5);
    // The resampled points correspond one to one (both start on the major axis): their
    // anatomical angles agree to the orientation error.
    ASSERT_EQ(r.bmo_anatomical_deg.size(), ph.truth.bmo_anatomical_deg.size());
    for (std::size_t i = 0; i < r.bmo_anatomical_deg.size(); ++i) {
        double d = std::fabs(r.bmo_anatomical_deg[i] - ph.truth.bmo_anatomical_deg[i]);
        d = std::min(d, 360.0 - d);
        EXPECT_LT(d, 1.0) << i;
    }
    // Sector means: this grid's MRW error is a few um (dy = 60 um); sectors differ by tens of
    // um between opposite clock hours of this tilted disc.
    for (std::size_t k = 0; k < 12; ++k) {
        EXPECT_NEAR(r.mrw_sector_mm[k], ph.truth.mrw_sector_mm[k], 0.008) << 30 * k;
    }
}

TEST(OnhAnalysis, IlmReleasingThePixelsIsTheSameSurface) {
    // The command's path without QC pictures: the level set frees the pixels, the surface is
    // the one the keeping path gives; the device source neither needs nor frees them.
    OnhPhantomParams p = reduced(OnhShape::kCupped);
    p.num_bscans = 25;
    p.num_ascans = 96;
    io::Scan scan = render_onh_scan(p);
    const IlmSurface kept = build_ilm_surface(scan, IlmSource::kLevelSet);
    const IlmSurface device = build_ilm_surface_releasing_pixels(scan, IlmSource::kDevice);
    EXPECT_TRUE(scan.pixels_loaded);
    EXPECT_FALSE(scan.bscans[0].pixels.empty());
    EXPECT_EQ(device.source, "device");
    const IlmSurface freed = build_ilm_surface_releasing_pixels(scan, IlmSource::kLevelSet);
    EXPECT_FALSE(scan.pixels_loaded);
    EXPECT_TRUE(scan.bscans[0].pixels.empty());
    EXPECT_EQ(freed.source, "levelset");
    ASSERT_EQ(kept.F.rows(), freed.F.rows());
    EXPECT_TRUE(kept.F == freed.F);
    EXPECT_TRUE(kept.V == freed.V);
    EXPECT_EQ(kept.notes, freed.notes);
}

TEST(OnhAnalysis, RefusesWhatIsNotAVolume) {
    io::Scan scan = render_onh_scan(reduced(OnhShape::kCupped));
    const IlmSurface ilm = device_ilm_surface(scan);
    io::Scan line = scan;
    line.meta.pattern = io::ScanPattern::kCircle;
    EXPECT_THROW((void)analyse_onh(line, ilm), AnalysisError);
    EXPECT_THROW((void)device_ilm_surface(line), AnalysisError);
    io::Scan no_distance = scan;
    no_distance.meta.distance_mm = 0.0;
    EXPECT_THROW((void)analyse_onh(no_distance, ilm), AnalysisError);
    EXPECT_THROW((void)ilm_source_from_string("levelsett"), UsageError);
    OnhParams bad;
    bad.bmo_points = 3;
    EXPECT_THROW(bad.validate(), UsageError);
}

// ---- Full-size phantoms against their truth (label "slow") ---------------------------------

struct Case {
    OnhPhantom ph;
    OnhResult r;
};

Case run_full(OnhShape shape) {
    Case c{make_onh_phantom(onh_phantom_preset(shape)), {}};
    c.r = analyse_onh(c.ph.scan, device_ilm_surface(c.ph.scan));
    return c;
}

// CONHT: the PL interpolation error at the centre, (dx^2 h_xx + dy^2 h_yy) / 8, with h'' <=
// |w''(0)| / b^2 (w in BMO radii, b the semi-minor axis), + 0.5 um for the BM depths' float32
// rounding and the centre's ~1 um offset (second order: h has zero slope at the centre).
double conht_bound(const OnhPhantomParams& p) {
    const OnhPhantomGeometry g(p);
    const double e = 1e-3;
    const double w2 = std::fabs(g.w(2 * e) - 2 * g.w(e) + g.w(0.0)) / (e * e);  // one-sided
    const double b = p.bmo_semi_minor_mm;
    return (g.scale_x_mm() * g.scale_x_mm() + g.distance_mm() * g.distance_mm()) * w2 /
               (8 * b * b) +
           5e-4;
}

void expect_common(const Case& c, const std::string& name) {
    const OnhTruth& t = c.ph.truth;
    const OnhResult& r = c.r;
    // BMO area: the 1 % (the ellipse fit averages the +-dx/2 end quantisation: ~0.2 %).
    EXPECT_NEAR(r.ellipse.area_mm2, t.bmo_area_mm2, 0.01 * t.bmo_area_mm2) << name;
    // Axes and centre: ~1 um from the fit; 5 um is > 4 sigma.
    EXPECT_NEAR(r.ellipse.semi_major_mm, t.bmo_semi_axes_mm[0], 0.005) << name;
    EXPECT_NEAR(r.ellipse.semi_minor_mm, t.bmo_semi_axes_mm[1], 0.005) << name;
    EXPECT_NEAR(r.ellipse.centre_mm.x(), t.bmo_centre_mm[0], 0.005) << name;
    EXPECT_NEAR(r.ellipse.centre_mm.y(), t.bmo_centre_mm[1], 0.005) << name;
    EXPECT_NEAR(r.bmo_orientation_anatomical_deg, t.bmo_orientation_anatomical_deg, 0.5) << name;
    // Outside the BMO every vertical line meets the ILM once (all presets): the graph is exact
    // there and V_av carries only the sampling errors above.
    EXPECT_NEAR(r.annular_volume_mm3, t.annular_volume_mm3, 0.01 * t.annular_volume_mm3) << name;
    EXPECT_LT(r.rpe_fill_outside_bmo_mm2, 0.01) << name;  // the gap is the BMO, nothing else
    EXPECT_TRUE(r.qc_flags.empty()) << name;
}

// 3-D MRW per point (issue 32 item 4; onh_mrw_points.h): the error of each of the 360 points
// is the BMO point's (its ends quantised within +-dx/2 along their B-scan, which the fitted
// ellipse inherits at worst; its height linear between ends one B-scan apart, off by
// z'' dy^2 / 8 << 0.1 um; the distance is 1-Lipschitz in the point) plus the surface's local
// error near the closest point (`surface_um`: the device graph is exact at the nodes, bilinear
// between them, < 1 um; the level set 4 um, its offset and speckle, docs/algorithms/
// levelset.md "Accuracy") plus the truth's largest 1 deg step (the matching). Neighbouring
// points (1 deg, ~16 um apart) differ by no more than the truth's own step + 1.5 um: the
// ellipse and the heights are smooth in angle, the mesh's normal errs by a few degrees
// (tan 5 deg x 16 um = 1.4 um).
// On the overhang's hidden wall the volume level set is rougher and further off: its mean MRW
// is 4.1 um short (docs/algorithms/onh.md) and its signed distance scatters by ~4.1 um SD
// (levelset.md "Staircase"), so `surface_um` = 8 there; and its marching-cubes facets span
// the 30 um between B-scans, where the closest point switches facets from one BMO point to
// the next: only the 1-Lipschitz bound |p_i+1 - p_i| holds for the jumps (`lipschitz_jumps`;
// measured 3.2 um against the truth's 0.5 um: open, docs/algorithms/onh.md "3-D MRW per point").
void expect_mrw_points(const OnhResult& r, const OnhTruth& t, double dx, double surface_um,
                       const std::string& name, bool lipschitz_jumps = false) {
    const MrwPointErrors e = mrw_point_errors(r, t);
    const double bound = 0.5 * dx + 1e-3 * surface_um + e.truth_jump_mm;
    std::printf("%-10s 3-D MRW points: worst error %.2f um (bound %.2f), largest 1 deg jump %.2f "
                "um (truth %.2f)\n",
                name.c_str(), 1e3 * e.worst_mm, 1e3 * bound, 1e3 * e.jump_mm, 1e3 * e.truth_jump_mm);
    EXPECT_LE(e.worst_mm, bound) << name;
    if (!lipschitz_jumps) {
        EXPECT_LE(e.jump_mm, e.truth_jump_mm + 0.0015) << name;
        return;
    }
    const std::size_t n = r.mrw_mm.size();
    for (std::size_t i = 0; i < n; ++i) {
        const std::size_t k = (i + 1) % n;
        EXPECT_LE(std::fabs(r.mrw_mm[k] - r.mrw_mm[i]),
                  (r.ellipse.points_mm[k] - r.ellipse.points_mm[i]).norm() + 1e-9)
            << name << " " << i;
    }
}

// Slow: a full-size ONH phantom (145 x 384 x 496): seconds, ~10x under the sanitizers.
SLOW_TEST(OnhPhantomTruth, CuppedWithDeviceIlm) {
    const Case c = run_full(OnhShape::kCupped);
    expect_common(c, "cupped");
    const OnhTruth& t = c.ph.truth;
    const OnhResult& r = c.r;
    EXPECT_NEAR(r.conht_mm, t.conht_mm, conht_bound(onh_phantom_preset(OnhShape::kCupped)));
    EXPECT_NEAR(r.cup_volume_mm3, t.cup_volume_mm3, 0.01 * t.cup_volume_mm3);
    EXPECT_NEAR(r.bmo_volume_mm3, t.bmo_volume_mm3, 0.01 * t.bmo_volume_mm3);
    EXPECT_NEAR(r.total_volume_mm3, t.total_volume_mm3, 0.01 * t.total_volume_mm3);
    // MRW: the BMO points' z linear between the measured ends (it was the nearest end's:
    // <= half a B-scan gap along the ellipse, |grad z_BM| ~ 0.1 x 15 um = 1.5 um, of either
    // sign), the ellipse ~1 um, the PL ILM < 0.5 um: 3 um.
    EXPECT_NEAR(r.mrw_mean_mm, t.mrw_mean_mm, 0.003);
    expect_mrw_points(r, t, c.ph.scan.meta.scale_x_mm, 1.0, "cupped");
}

// Slow: a full-size ONH phantom (145 x 384 x 496): seconds, ~10x under the sanitizers.
// Release only (ACCURACY_TEST); under the sanitizers its code paths run in
// OnhPhantomTruth.CuppedWithDeviceIlm.
ACCURACY_TEST(OnhPhantomTruth, SwollenWithDeviceIlm) {
    const Case c = run_full(OnhShape::kSwollen);
    expect_common(c, "swollen");
    const OnhTruth& t = c.ph.truth;
    const OnhResult& r = c.r;
    EXPECT_NEAR(r.conht_mm, t.conht_mm, conht_bound(onh_phantom_preset(OnhShape::kSwollen)));
    EXPECT_EQ(r.cup_volume_mm3, 0.0);
    EXPECT_NEAR(r.bmo_volume_mm3, t.bmo_volume_mm3, 0.01 * t.bmo_volume_mm3);
    EXPECT_NEAR(r.total_volume_mm3, t.total_volume_mm3, 0.01 * t.total_volume_mm3);
    EXPECT_NEAR(r.mrw_mean_mm, t.mrw_mean_mm, 0.003);
    expect_mrw_points(r, t, c.ph.scan.meta.scale_x_mm, 1.0, "swollen");
}

// Slow: a full-size ONH phantom (145 x 384 x 496): seconds, ~10x under the sanitizers.
// Release only (ACCURACY_TEST); under the sanitizers its code paths run in
// OnhPhantomTruth.CuppedWithDeviceIlm.
ACCURACY_TEST(OnhPhantomTruth, OverhangWithDeviceIlmIsBlindToTheCavity) {
    const Case c = run_full(OnhShape::kOverhang);
    expect_common(c, "overhang");
    const OnhTruth& t = c.ph.truth;
    const OnhResult& r = c.r;
    // The centre line meets the ILM once: CONHT is as exact as for the other shapes.
    EXPECT_NEAR(r.conht_mm, t.conht_mm, conht_bound(onh_phantom_preset(OnhShape::kOverhang)));
    // The device line is the top crossing: over the cavity it reports the lip, so the graph
    // holds tissue where the cavity's vitreous is. Per vertical line the truth's signed sum
    // (top - middle + bottom crossing) <= top; hence inside the BMO the graph's volume is
    // larger and its cup smaller than the truth's -- by more than the 1 % sampling bound.
    EXPECT_GT(r.bmo_volume_mm3, t.bmo_volume_mm3 * 1.01);
    EXPECT_LT(r.cup_volume_mm3, t.cup_volume_mm3 * 0.99);
    // MRW: the BMO points lie in tissue (checked below); the graph's vitreous is a subset of
    // the true vitreous (the cavity is missing), so the distance to it can only be larger.
    const OnhPhantomGeometry g(onh_phantom_preset(OnhShape::kOverhang));
    for (const auto& p : t.bmo_points_mm) {
        ASSERT_TRUE(g.in_tissue(p.x(), p.y(), p.z() + 1e-6));
    }
    EXPECT_GT(r.mrw_mean_mm, t.mrw_mean_mm + 0.003);
    RecordProperty("device_mrw_mean_mm", std::to_string(r.mrw_mean_mm));
    RecordProperty("truth_mrw_mean_mm", std::to_string(t.mrw_mean_mm));
}

// ---- The same phantoms with the level-set ILM (the default source; label "slow") ----------

struct LevelSetCase {
    OnhPhantom ph;
    OnhResult device;
    OnhResult levelset;
};

LevelSetCase run_both(OnhShape shape) {
    LevelSetCase c{make_onh_phantom(onh_phantom_preset(shape)), {}, {}};
    c.device = analyse_onh(c.ph.scan, device_ilm_surface(c.ph.scan));
    c.levelset = analyse_onh(c.ph.scan, levelset_ilm_surface(c.ph.scan));
    const OnhTruth& t = c.ph.truth;
    const auto row = [&](const char* name, double truth, double dev, double ls, double unit) {
        std::printf("[ onh %-8s] %-18s truth %10.6f  device %+9.4f  levelset %+9.4f %s\n",
                    to_string(shape).c_str(), name, truth, (dev - truth) * unit,
                    (ls - truth) * unit, unit == 1000.0 ? "um" : "%");
    };
    const auto pct = [](double truth) { return truth != 0.0 ? 100.0 / truth : 0.0; };
    row("cup_volume", t.cup_volume_mm3, c.device.cup_volume_mm3, c.levelset.cup_volume_mm3,
        pct(t.cup_volume_mm3));
    row("bmo_volume", t.bmo_volume_mm3, c.device.bmo_volume_mm3, c.levelset.bmo_volume_mm3,
        pct(t.bmo_volume_mm3));
    row("total_volume", t.total_volume_mm3, c.device.total_volume_mm3,
        c.levelset.total_volume_mm3, pct(t.total_volume_mm3));
    row("annular_volume", t.annular_volume_mm3, c.device.annular_volume_mm3,
        c.levelset.annular_volume_mm3, pct(t.annular_volume_mm3));
    row("conht", t.conht_mm, c.device.conht_mm, c.levelset.conht_mm, 1000.0);
    row("mrw_mean", t.mrw_mean_mm, c.device.mrw_mean_mm, c.levelset.mrw_mean_mm, 1000.0);
    row("bmo_area", t.bmo_area_mm2, c.device.ellipse.area_mm2, c.levelset.ellipse.area_mm2,
        pct(t.bmo_area_mm2));
    row("mrw_area", t.mrw_area_mm2, c.device.mrw_area_mm2, c.levelset.mrw_area_mm2,
        pct(t.mrw_area_mm2));
    return c;
}

// The targets with the level-set ILM: BMO area within 1 % (the BMO does not depend on
// the ILM), CONHT and mean MRW within 5 um (the level set's remaining offset is 1-2 um towards
// the vitreous, docs/algorithms/levelset.md "Where the zero level settles", plus the 1-2 um
// sampling of the device case), every volume within the 2 %.
void expect_levelset_targets(const LevelSetCase& c, const std::string& name) {
    const OnhTruth& t = c.ph.truth;
    const OnhResult& r = c.levelset;
    EXPECT_NEAR(r.ellipse.area_mm2, t.bmo_area_mm2, 0.01 * t.bmo_area_mm2) << name;
    EXPECT_NEAR(r.conht_mm, t.conht_mm, 0.005) << name;
    EXPECT_NEAR(r.mrw_mean_mm, t.mrw_mean_mm, 0.005) << name;
    for (const auto& [label, value, truth] :
         {std::tuple{"bmo", r.bmo_volume_mm3, t.bmo_volume_mm3},
          std::tuple{"total", r.total_volume_mm3, t.total_volume_mm3},
          std::tuple{"annular", r.annular_volume_mm3, t.annular_volume_mm3},
          std::tuple{"cup", r.cup_volume_mm3, t.cup_volume_mm3}}) {
        EXPECT_NEAR(value, truth, 0.02 * truth) << name << " " << label;
    }
    // MRW area (Eq. 8.23) within the 2 %, or, where the MRW lengths themselves are off
    // (the overhang: the level set's mean MRW is 4 um = 2.5 % short under the lip), within that
    // relative MRW error + 0.5 %: the strip's area is its perimeter times its mean width, so a
    // relative error of the widths carries into it one to one.
    const double area_err = std::fabs(r.mrw_area_mm2 / t.mrw_area_mm2 - 1.0);
    const double mrw_err = std::fabs(r.mrw_mean_mm / t.mrw_mean_mm - 1.0);
    EXPECT_LE(area_err, std::max(0.02, mrw_err + 0.005)) << name << " mrw area";
    // No leak on a clean eye (docs/algorithms/levelset.md "Leaks"), overhang included.
    for (const std::string& f : r.qc_flags) {
        EXPECT_EQ(f.find("level-set front leaked"), std::string::npos) << name << ": " << f;
    }
    const bool overhang = name == "overhang";
    expect_mrw_points(r, t, c.ph.scan.meta.scale_x_mm, overhang ? 8.0 : 4.0, name + " LS",
                      overhang);
}

// The reduced cupped volume (73 x 192: A-scans 22.7 um, B-scans 60.4 um apart) with vessel
// shadows and device-line faults, level-set ILM: the cup volume within the 2 %. The
// despeckle's x blur is capped at the width the defaults were measured with (1 px of the
// 384-A-scan scans, 11.4 um); 1 px at 22.7 um moved the steep cup wall towards the vitreous,
// more under the bright vessel lumens, and missed it (-2.22 %, docs/algorithms/levelset.md
// "Coarse A-scan spacing"). Measured -1.56 %; the device graph of the same scan -0.80 % (the
// sampling of the BMO and the RPE), the level set's offset towards the vitreous (1-2 um over
// ~0.9 mm2 of cup surface) the rest.
TEST(OnhPhantomTruth, ReducedCuppedVolumeWithShadowsMeetsTheCupVolumeWithoutAFold) {
    OnhPhantomParams p = onh_phantom_preset(OnhShape::kCupped);
    p.num_bscans = 73;
    p.num_ascans = 192;
    p.artefacts.vessel_shadows = true;
    p.artefacts.segmentation_faults = true;
    const OnhPhantom ph = make_onh_phantom(p);
    const OnhResult r = analyse_onh(ph.scan, levelset_ilm_surface(ph.scan));
    const OnhTruth& t = ph.truth;
    std::printf("reduced cupped volume, shadows, level set: cup volume %+.2f %%, facing down "
                "%.2g mm2\n",
                100.0 * (r.cup_volume_mm3 / t.cup_volume_mm3 - 1.0),
                r.ilm_quality.negative_projected_area_mm2);
    EXPECT_NEAR(r.cup_volume_mm3, t.cup_volume_mm3, 0.02 * t.cup_volume_mm3);
    // No fold: the true ILM is a height field here, so nothing of the final mesh may face down
    // but slivers. Bound: a hundredth of a grid cell (1.4e-5 mm2); a leak's fold covers cells
    // (radial leak phantom: 7.2e-5 mm2), and the slivers RoFi turned over where the zero level
    // passed through a voxel came to 2.3e-5 mm2 here before marching cubes kept the points a
    // tenth of a pixel off the voxels (measured now 6e-7; docs/algorithms/levelset.md "Folds").
    EXPECT_LE(r.ilm_quality.negative_projected_area_mm2,
              0.01 * ph.scan.meta.scale_x_mm * ph.scan.meta.distance_mm);
}

// Slow: a full-size ONH phantom (145 x 384 x 496): seconds, ~10x under the sanitizers.
SLOW_TEST(OnhPhantomTruth, CuppedWithLevelSetIlm) {
    const LevelSetCase c = run_both(OnhShape::kCupped);
    expect_levelset_targets(c, "cupped");
}

// Slow: a full-size ONH phantom (145 x 384 x 496): seconds, ~10x under the sanitizers.
// Release only (ACCURACY_TEST); under the sanitizers its code paths run in
// OnhPhantomTruth.CuppedWithLevelSetIlm.
ACCURACY_TEST(OnhPhantomTruth, SwollenWithLevelSetIlm) {
    const LevelSetCase c = run_both(OnhShape::kSwollen);
    expect_levelset_targets(c, "swollen");
}

// The point of the 3-D ILM: under the rim lip the level set follows the cavity the device
// graph cannot see, so inside the BMO it is closer to the truth in every parameter the cavity
// touches.
// Slow: a full-size ONH phantom (145 x 384 x 496): seconds, ~10x under the sanitizers.
// Release only (ACCURACY_TEST); under the sanitizers its code paths run in
// OnhPhantomTruth.CuppedWithLevelSetIlm and LevelSetPhantom.Overhang.
ACCURACY_TEST(OnhPhantomTruth, OverhangLevelSetIsCloserToTheTruthThanTheDeviceGraph) {
    const LevelSetCase c = run_both(OnhShape::kOverhang);
    expect_levelset_targets(c, "overhang");
    const OnhTruth& t = c.ph.truth;
    EXPECT_LT(std::fabs(c.levelset.bmo_volume_mm3 - t.bmo_volume_mm3),
              std::fabs(c.device.bmo_volume_mm3 - t.bmo_volume_mm3));
    EXPECT_LT(std::fabs(c.levelset.cup_volume_mm3 - t.cup_volume_mm3),
              std::fabs(c.device.cup_volume_mm3 - t.cup_volume_mm3));
    EXPECT_LT(std::fabs(c.levelset.mrw_mean_mm - t.mrw_mean_mm),
              std::fabs(c.device.mrw_mean_mm - t.mrw_mean_mm));
    EXPECT_LT(std::fabs(c.levelset.mrw_area_mm2 - t.mrw_area_mm2),
              std::fabs(c.device.mrw_area_mm2 - t.mrw_area_mm2));
}

}  // namespace
}  // namespace octshape::retina
