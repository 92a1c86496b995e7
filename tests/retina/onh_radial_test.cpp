// The ONH analysis on radial scans (onh_radial.cpp) against the radial ONH phantoms' truth:
// the same continuous eyes as the volume phantoms, the in-plane MRW truth from a dense search
// in each line's plane (phantom_onh.h), never from sampled lines or pixels.
//
// Sampling of the default radial phantom: 24 lines of 4.35 mm, 384 A-scans (ds = 11.4 um), 7.5
// deg apart (0.11 mm at the BMO). The error sources and their sizes (docs/algorithms/onh.md,
// "Radial scans"):
//  * BMO points: each gap end half-way between the last present and the first missing A-scan:
//    uniform within +-ds/2 along its line (sigma 3.3 um), zero mean; 48 points: the area's
//    relative SD ~ 2 x 3.3 um / 0.84 mm / sqrt(24) = 0.16 %. The 1 % is > 6 sigma.
//  * Surfaces between the lines: linear in angle at constant distance from the crossing. On
//    the phantoms' (elliptical, tilted, curved) eyes with the crossing up to 500 um from the
//    BMO centre it costs < 0.8 % of any volume (measured: docs "Radial scans"); the 2 %
//    holds with a margin of > 2.5x.
//  * CONHT: the ILM at the BMO centre interpolated between two lines ~r x 7.5 deg apart and
//    the thin-plate RPE from exact BM: measured < 1 um; the 5 um.
//  * MRW (3-D and in-plane): the BMO ends' +-ds/2 moves a point along its line, the MRW by
//    <= ds/2 x |cos| of the wall angle (< 5.7 um per point, zero mean over 48 points: ~1 um);
//    the 3-D MRW's ellipse points take z from the nearest measured end (7.5 deg away: |grad
//    z_BM| ~ 0.1 x 55 um = 5.5 um per point, of either sign). The 5 um.
// The overhang's device ILM is the envelope of the cavity, as for a volume (onh_test.cpp): its
// V_bmo, V_cup, V_tv and both MRWs miss the truth by what the envelope holds, asserted as such.

#include "octshape/retina/onh.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "octshape/error.h"
#include "octshape/retina/axial_registration.h"
#include "octshape/retina/phantom_onh.h"
#include "octshape/retina/radial_geometry.h"
#include "onh_mrw_points.h"
#include "slow_test.h"

namespace octshape::retina {
namespace {

OnhPhantomParams radial_params(OnhShape shape, io::Laterality eye = io::Laterality::kOD,
                               double offset_um = 0.0, int lines = 24) {
    OnhPhantomParams p = onh_phantom_preset(shape);
    p.eye = eye;
    p.radial = true;
    p.radial_lines = lines;
    p.crossing_offset_um = offset_um;
    return p;
}

TEST(OnhRadialPhantom, LinesCrossWhereTheTruthSaysAndSampleTheVolumesEye) {
    const OnhPhantomParams p = radial_params(OnhShape::kCupped, io::Laterality::kOS, 120.0, 12);
    const io::Scan scan = render_onh_scan(p);
    EXPECT_EQ(scan.meta.pattern, io::ScanPattern::kRadial);
    EXPECT_EQ(scan.num_bscans(), 12);
    EXPECT_EQ(scan.meta.distance_mm, 0.0);
    const RadialGeometry g = radial_geometry(scan);
    EXPECT_TRUE(g.regular);
    EXPECT_LT(g.max_miss_mm, 1e-9);
    EXPECT_NEAR(g.mean_length_mm, p.line_length_mm, 1e-9);
    // Every line's middle A-scan position is the crossing (the sample points, grid frame).
    const std::vector<Eigen::Vector2d> pts = onh_sample_points(p);
    ASSERT_EQ(pts.size(), static_cast<std::size_t>(12 * p.num_ascans));
    const Eigen::Vector2d c = onh_radial_crossing(p);
    OnhPhantomParams vol = p;
    vol.radial = false;
    const OnhPhantomGeometry gv(vol);
    EXPECT_NEAR((c - gv.bmo_centre()).x(), 0.120, 1e-12);  // the same eye: BMO centre + offset
    for (int k = 0; k < 12; ++k) {
        const Eigen::Vector2d a = pts[static_cast<std::size_t>(k * p.num_ascans)];
        const Eigen::Vector2d b = pts[static_cast<std::size_t>((k + 1) * p.num_ascans - 1)];
        EXPECT_NEAR((0.5 * (a + b) - c).norm(), 0.0, 1e-12);
        EXPECT_NEAR((b - a).norm(), p.line_length_mm, 1e-12);
    }
}

TEST(OnhRadialPhantom, CrossingOffsetInAnyDirection) {
    // crossing_offset_y_um moves the crossing along grid +y (the re-scan bench places it in
    // every direction); the lines still cross there, and the 500 um bound is on the distance.
    OnhPhantomParams p = radial_params(OnhShape::kCupped, io::Laterality::kOD, 60.0, 12);
    p.crossing_offset_y_um = -80.0;
    OnhPhantomParams vol = p;
    vol.radial = false;
    const Eigen::Vector2d c = onh_radial_crossing(p);
    EXPECT_NEAR((c - OnhPhantomGeometry(vol).bmo_centre() - Eigen::Vector2d(0.060, -0.080)).norm(),
                0.0, 1e-12);
    const std::vector<Eigen::Vector2d> pts = onh_sample_points(p);
    for (int k = 0; k < 12; ++k) {
        const Eigen::Vector2d a = pts[static_cast<std::size_t>(k * p.num_ascans)];
        const Eigen::Vector2d b = pts[static_cast<std::size_t>((k + 1) * p.num_ascans - 1)];
        EXPECT_NEAR((0.5 * (a + b) - c).norm(), 0.0, 1e-12);
    }
    p.crossing_offset_um = 400.0;
    p.crossing_offset_y_um = 400.0;  // each within 500 um, the distance 566 um is not
    try {
        p.validate();
        ADD_FAILURE() << "a crossing 566 um from the BMO centre was accepted";
    } catch (const UsageError& e) {
        EXPECT_NE(std::string(e.what()).find("crossing_offset_y_um"), std::string::npos) << e.what();
    }
}

TEST(OnhRadialPhantom, InplaneTruthIsNeverShorterThanTheSurfaceDistance) {
    // The closest point of the ILM curve in a plane is a point of the ILM surface: the in-plane
    // MRW is >= the 3-D distance from the same BMO point. With the crossing at the BMO centre
    // and a rotationally symmetric disc (a = b) the closest point lies in the radial plane: both
    // are equal.
    OnhPhantomParams p = radial_params(OnhShape::kCupped);
    p.bmo_semi_major_mm = p.bmo_semi_minor_mm = 0.85;
    p.bmo_rotation_deg = 0.0;
    p.tilt_x = p.tilt_y = 0.0;
    p.radial_lines = 6;
    OnhTruthOptions o;
    o.mrw_points = 12;  // parameter angles k 30 deg: the lines' BMO points (6 lines, 30 deg)
    const OnhTruth t = compute_onh_truth(p, o);
    ASSERT_TRUE(t.has_inplane);
    ASSERT_EQ(t.inplane.mrw_mm.size(), 12U);
    for (std::size_t i = 0; i < 12; ++i) {
        EXPECT_GT(t.inplane.mrw_mm[i], 0.1);
        EXPECT_LT(t.inplane.abs_change_mm, 1e-9);
    }
    EXPECT_NEAR(t.inplane.mean_mm, t.mrw_mean_mm, 1e-7);
    // An elliptical BMO: each in-plane value >= the surface distance from that point, which is
    // at least the 3-D minimum.
    const OnhTruth e = compute_onh_truth(radial_params(OnhShape::kCupped));
    EXPECT_GE(e.inplane.min_mm, e.mrw_min_mm - 1e-9);
    EXPECT_GE(e.inplane.max_mm, e.mrw_max_mm - 2e-6);  // the max over 48 vs 360 points
}

TEST(OnhRadial, RefusesWhatItCannotDoAndImpossibleGeometry) {
    OnhPhantomParams p = radial_params(OnhShape::kCupped, io::Laterality::kOD, 0.0, 6);
    p.num_ascans = 128;
    const io::Scan scan = render_onh_scan(p);
    EXPECT_NO_THROW(require_onh_scan(scan));
    const IlmSurface ilm = device_ilm_surface(scan);
    std::vector<BmoPoint> file(6);  // points without their B-scans (not read_radial_bmo_csv's)
    EXPECT_THROW((void)analyse_onh(scan, ilm, {}, file), UsageError);
    // All lines parallel: no crossing.
    io::Scan parallel = scan;
    for (std::size_t k = 0; k < parallel.bscans.size(); ++k) {
        parallel.bscans[k] = scan.bscans[0];
        parallel.bscans[k].start_y_mm += 0.1 * static_cast<double>(k);
        parallel.bscans[k].end_y_mm += 0.1 * static_cast<double>(k);
    }
    EXPECT_THROW(require_onh_scan(parallel), AnalysisError);
    // A line with Start = End.
    io::Scan degenerate = scan;
    degenerate.bscans[2].end_x_mm = degenerate.bscans[2].start_x_mm;
    degenerate.bscans[2].end_y_mm = degenerate.bscans[2].start_y_mm;
    EXPECT_THROW(require_onh_scan(degenerate), AnalysisError);
    // Lines that end next to their crossing (all starting at it).
    io::Scan half = scan;
    for (auto& b : half.bscans) {
        b.start_x_mm = 0.5 * (b.start_x_mm + b.end_x_mm);
        b.start_y_mm = 0.5 * (b.start_y_mm + b.end_y_mm);
    }
    EXPECT_THROW(require_onh_scan(half), AnalysisError);
    // Only 2 lines.
    io::Scan two = scan;
    two.bscans.resize(2);
    EXPECT_THROW(require_onh_scan(two), AnalysisError);
}

// ---- Default radial phantoms against their truth (label "slow") ---------------------------

struct RadialCase {
    OnhPhantom ph;
    OnhResult r;
};

RadialCase run_radial(const OnhPhantomParams& p, IlmSource source = IlmSource::kDevice) {
    RadialCase c{make_onh_phantom(p), {}};
    c.r = analyse_onh(c.ph.scan, build_ilm_surface(c.ph.scan, source));
    return c;
}

void print_row(const std::string& name, const RadialCase& c) {
    const OnhTruth& t = c.ph.truth;
    const OnhResult& r = c.r;
    auto pct = [](double a, double b) { return b != 0.0 ? 100.0 * (a / b - 1.0) : 0.0; };
    std::printf(
        "%-22s BMO area %+.2f %%  V_cup %+.2f %%  V_bmo %+.2f %%  V_tv %+.2f %%  V_av %+.2f %%  "
        "CONHT %+.2f um  MRW %+.2f um  MRW in-plane %+.2f um  MRW area %+.2f %%  E_b %+.4f  "
        "(%.2f s)\n",
        name.c_str(), pct(r.ellipse.area_mm2, t.bmo_area_mm2),
        pct(r.cup_volume_mm3, t.cup_volume_mm3), pct(r.bmo_volume_mm3, t.bmo_volume_mm3),
        pct(r.total_volume_mm3, t.total_volume_mm3),
        pct(r.annular_volume_mm3, t.annular_volume_mm3), 1e3 * (r.conht_mm - t.conht_mm),
        1e3 * (r.mrw_mean_mm - t.mrw_mean_mm), 1e3 * (r.mrw_inplane_mean_mm - t.inplane.mean_mm),
        pct(r.mrw_area_mm2, t.mrw_area_mm2), r.bending_energy - t.bending_energy, r.seconds);
}

// 3-D MRW per point (issue 32 item 4): the 360 resampled BMO points against the truth's point
// at the nearest anatomical angle (onh_mrw_points.h; the match moves the true MRW by <= its
// largest 1 deg step, added to the bound). The measured 3-D MRW is the exact distance to
// the mesh, 1-Lipschitz in the BMO point; its error per point is the BMO point's (the fitted
// ellipse within ds/2 of the true one where the 48 ends are, each end within +-ds/2 along its
// line; the height linear in angle between two ends 7.5 deg apart, off by A dtheta^2 / 8 <=
// 0.1 um for a BM tilt A <= 50 um across the BMO) plus the surface's error near the closest
// point (`surface_um`: the device ILM is exact on the lines and interpolated between them,
// < 1 um of height at the rim; the level set as the in-plane bound below, 4 um).
// Neighbouring points are 1 deg (~16 um) apart: their errors differ by what the error sources
// change over 16 um. The ellipse and now the BMO height are smooth in angle, the mesh's normal
// errs by a few degrees (tan 5 deg x 16 um = 1.4 um): a jump beyond the truth's own by more
// than 1.5 um is not the geometry's. (The height used to be the nearest measured end's, a step
// function: jumps of 2-10 um on these phantoms, 40-44 um on a real eye whose lines were not
// registered in depth.)
void expect_mrw_points(const RadialCase& c, double surface_um, const std::string& name) {
    ASSERT_EQ(c.r.mrw_mm.size(), 360U) << name;
    const MrwPointErrors e = mrw_point_errors(c.r, c.ph.truth);
    const double ds = c.ph.scan.meta.scale_x_mm;
    const double bound = 0.5 * ds + 1e-3 * surface_um + e.truth_jump_mm;
    std::printf("%-22s 3-D MRW points: worst error %.2f um (bound %.2f), largest 1 deg jump %.2f um "
                "(truth %.2f)\n",
                name.c_str(), 1e3 * e.worst_mm, 1e3 * bound, 1e3 * e.jump_mm, 1e3 * e.truth_jump_mm);
    EXPECT_LE(e.worst_mm, bound) << name;
    EXPECT_LE(e.jump_mm, e.truth_jump_mm + 0.0015) << name;
}

// What every shape meets with the device ILM: the BMO, the annulus (one crossing per vertical
// line outside the BMO) and CONHT (the centre line meets the ILM once).
void expect_common(const RadialCase& c, const std::string& name) {
    const OnhTruth& t = c.ph.truth;
    const OnhResult& r = c.r;
    EXPECT_TRUE(r.radial) << name;
    EXPECT_EQ(r.bmo_measured.size(), 2U * static_cast<std::size_t>(c.ph.scan.num_bscans())) << name;
    EXPECT_NEAR(r.ellipse.area_mm2, t.bmo_area_mm2, 0.01 * t.bmo_area_mm2) << name;
    // The orientation in anatomical degrees (OD and OS alike: the truth's convention).
    EXPECT_NEAR(r.bmo_orientation_anatomical_deg, t.bmo_orientation_anatomical_deg, 1.0) << name;
    EXPECT_NEAR(r.annular_volume_mm3, t.annular_volume_mm3, 0.02 * t.annular_volume_mm3) << name;
    EXPECT_NEAR(r.conht_mm, t.conht_mm, 0.005) << name;
    EXPECT_TRUE(r.qc_flags.empty()) << name;
    ASSERT_EQ(r.mrw_inplane.size(), r.bmo_measured.size()) << name;
}

void expect_accurate(const RadialCase& c, const std::string& name) {
    expect_common(c, name);
    const OnhTruth& t = c.ph.truth;
    const OnhResult& r = c.r;
    if (t.has_cup) {
        EXPECT_NEAR(r.cup_volume_mm3, t.cup_volume_mm3, 0.02 * t.cup_volume_mm3) << name;
    } else {
        EXPECT_EQ(r.cup_volume_mm3, 0.0) << name;
    }
    EXPECT_NEAR(r.bmo_volume_mm3, t.bmo_volume_mm3, 0.02 * t.bmo_volume_mm3) << name;
    EXPECT_NEAR(r.total_volume_mm3, t.total_volume_mm3, 0.02 * t.total_volume_mm3) << name;
    EXPECT_NEAR(r.mrw_mean_mm, t.mrw_mean_mm, 0.005) << name;
    EXPECT_NEAR(r.mrw_inplane_mean_mm, t.inplane.mean_mm, 0.005) << name;
    // Per BMO point (matched by line and side): the distance to a curve is 1-Lipschitz in the
    // point, so the end's +-ds/2 along its line moves the in-plane MRW by <= ds/2 (5.7 um);
    // + 1 um for the PL ILM line and the extrapolated z.
    const double ds = c.ph.scan.meta.scale_x_mm;  // the lines' A-scan spacing
    for (const InplaneMrw& m : r.mrw_inplane) {
        const std::size_t i = 2 * static_cast<std::size_t>(m.bscan) + (m.side < 0 ? 0 : 1);
        ASSERT_LT(i, t.inplane.mrw_mm.size()) << name;
        EXPECT_NEAR(m.mrw_mm, t.inplane.mrw_mm[i], 0.5 * ds + 0.001)
            << name << " B-scan " << m.bscan << " side " << m.side;
        const double da = std::fmod(std::fabs(m.anatomical_deg - t.inplane.anatomical_deg[i]), 360.0);
        EXPECT_LT(std::min(da, 360.0 - da), 0.5) << name;
    }
    // Per clock hour (~4 points each), the anatomical convention of the truth (OS mirrored):
    // only where no truth point lies within 0.5 deg of the sector's edges. With the crossing at
    // the BMO centre 24 lines put a BMO point exactly on every edge (15 + 30 k deg are
    // multiples of 7.5), and the measured angle (+-0.2 deg about the fitted centre) decides its
    // sector: a swap moves a 4-point mean by ~6-8 um (measured), a property of clock hours on
    // radial lines, not an error of either MRW (docs/algorithms/onh.md "Radial scans").
    for (std::size_t k = 0; k < 12; ++k) {
        if (t.inplane.sector_points[k] == 0) continue;
        bool on_edge = false;
        for (const double deg : t.inplane.anatomical_deg) {
            for (const double edge : {30.0 * k - 15.0, 30.0 * k + 15.0}) {
                const double d = std::fmod(std::fabs(deg - edge) + 360.0, 360.0);
                on_edge = on_edge || std::min(d, 360.0 - d) < 0.5;
            }
        }
        if (on_edge) continue;
        EXPECT_NEAR(r.mrw_inplane_sector_mm[k], t.inplane.sector_mm[k], 0.005)
            << name << " sector " << 30 * k;
    }
    // The MRW area within 2 % (Eq. 8.23 on the low-passed closest-point curve).
    EXPECT_NEAR(r.mrw_area_mm2, t.mrw_area_mm2, 0.02 * t.mrw_area_mm2) << name;
    expect_mrw_points(c, 1.0, name);
    // No face facing down: the phantom's ILM is nowhere steeper than ~65 deg outside the
    // overhang, and a graph mesh has none.
    EXPECT_EQ(r.ilm_quality.negative_projected_area_mm2, 0.0) << name;
}

// Slow: four radial phantoms and their truths (~1.5 s each).
SLOW_TEST(OnhRadialTruth, CuppedAndSwollenBothEyes) {
    for (const OnhShape shape : {OnhShape::kCupped, OnhShape::kSwollen}) {
        for (const io::Laterality eye : {io::Laterality::kOD, io::Laterality::kOS}) {
            const std::string name =
                to_string(shape) + (eye == io::Laterality::kOD ? " OD" : " OS");
            const RadialCase c = run_radial(radial_params(shape, eye));
            print_row(name, c);
            expect_accurate(c, name);
        }
    }
}

// Slow: the crossing 300 um from the BMO centre (the interpolation between lines then spans
// the BMO asymmetrically), 12 and 48 lines.
// Release only (ACCURACY_TEST); under the sanitizers its code paths run in
// OnhRadialTruth.CuppedAndSwollenBothEyes.
ACCURACY_TEST(OnhRadialTruth, CrossingOffsetAndLineCount) {
    for (const auto& [offset, lines] : {std::pair<double, int>{300.0, 24}, {0.0, 12}, {0.0, 48}}) {
        const std::string name = "cupped " + std::to_string(lines) + " lines " +
                                 std::to_string(static_cast<int>(offset)) + " um";
        const RadialCase c =
            run_radial(radial_params(OnhShape::kCupped, io::Laterality::kOD, offset, lines));
        print_row(name, c);
        expect_accurate(c, name);
    }
}

// Slow: the overhanging disc, both eyes. The device line is the top crossing: over the cavity
// it reports the lip, as in a volume (onh_test.cpp "OverhangWithDeviceIlmIsBlindToTheCavity"):
// the BMO, the annulus and CONHT are right, the cavity's volumes and both MRWs are not (their
// true closest points lie in the cavity). Not a target met: measured and asserted as the
// envelope's known error; only a level-set ILM could meet it, which radial scans lack.
// Release only (ACCURACY_TEST); under the sanitizers its code paths run in
// OnhRadialTruth.CuppedAndSwollenBothEyes.
ACCURACY_TEST(OnhRadialTruth, OverhangWithDeviceIlmIsBlindToTheCavity) {
    for (const io::Laterality eye : {io::Laterality::kOD, io::Laterality::kOS}) {
        const std::string name = std::string("overhang ") + (eye == io::Laterality::kOD ? "OD" : "OS");
        const RadialCase c = run_radial(radial_params(OnhShape::kOverhang, eye));
        print_row(name, c);
        expect_common(c, name);
        const OnhTruth& t = c.ph.truth;
        const OnhResult& r = c.r;
        EXPECT_GT(r.bmo_volume_mm3, 1.05 * t.bmo_volume_mm3) << name;
        EXPECT_LT(r.cup_volume_mm3, t.cup_volume_mm3) << name;
        EXPECT_GT(r.mrw_mean_mm, t.mrw_mean_mm + 0.05) << name;
        EXPECT_GT(r.mrw_inplane_mean_mm, t.inplane.mean_mm + 0.05) << name;
    }
}

// ---- The level-set ILM on radial scans ------------------------------------------------------
//
// The 2-D level set per B-scan is the volume's (docs/algorithms/levelset.md) on one B-scan: its
// zero level settles 1-3 um above the true ILM (towards the vitreous; "Where the zero level
// settles"), and under the overhang's lip slightly into the cavity. Interpolating the signed
// distances between the lines costs what the device heights' interpolation costs (< 0.8 % of a
// volume, above). So the same targets hold as for the device ILM on the cupped and swollen
// eyes, and now on the overhang: volumes 2 %, BMO area 1 %, CONHT and both mean MRWs 5 um, MRW
// area 2 %. Per in-plane point the error is the BMO end's quantisation (uniform within +-ds/2
// along the line, RMS ds/sqrt(12) = 3.3 um; 1-Lipschitz) plus the level-set curve's local error
// where the closest point lies, which, unlike the device line's, is not exact and varies with
// the speckle from point to point (measured per point up to 12 um on the overhang at 12 lines,
// where the curve reaches a little into the cavity under the lip). So the per-point errors are
// bounded by their RMS: <= ds/sqrt(12) + 4 um (RMS of a sum <= sum of the RMS; 4 um for the
// curve: the volume's level set is 3.5 um mean |d| on the reduced overhang and 3.9 um on its
// hidden wall, levelset.md "Accuracy").

// The level set's targets against the truth (without expect_common's checks of the flags and
// the measured points).
void expect_levelset_targets(const RadialCase& c, const std::string& name, bool overhang) {
    const OnhTruth& t = c.ph.truth;
    const OnhResult& r = c.r;
    EXPECT_EQ(r.ilm_source, "levelset") << name;
    if (t.has_cup) {
        EXPECT_NEAR(r.cup_volume_mm3, t.cup_volume_mm3, 0.02 * t.cup_volume_mm3) << name;
    } else {
        // No cup in the truth: the surface sits above the RPE everywhere (1-3 um offset up).
        EXPECT_EQ(r.cup_volume_mm3, 0.0) << name;
    }
    EXPECT_NEAR(r.bmo_volume_mm3, t.bmo_volume_mm3, 0.02 * t.bmo_volume_mm3) << name;
    EXPECT_NEAR(r.total_volume_mm3, t.total_volume_mm3, 0.02 * t.total_volume_mm3) << name;
    EXPECT_NEAR(r.mrw_mean_mm, t.mrw_mean_mm, 0.005) << name;
    EXPECT_NEAR(r.mrw_inplane_mean_mm, t.inplane.mean_mm, 0.005) << name;
    EXPECT_NEAR(r.mrw_area_mm2, t.mrw_area_mm2, 0.02 * t.mrw_area_mm2) << name;
    const double ds = c.ph.scan.meta.scale_x_mm;
    double worst = 0.0;
    double sum2 = 0.0;
    for (const InplaneMrw& m : r.mrw_inplane) {
        const std::size_t i = 2 * static_cast<std::size_t>(m.bscan) + (m.side < 0 ? 0 : 1);
        ASSERT_LT(i, t.inplane.mrw_mm.size()) << name;
        const double e = m.mrw_mm - t.inplane.mrw_mm[i];
        worst = std::max(worst, std::fabs(e));
        sum2 += e * e;
    }
    const double rms = std::sqrt(sum2 / static_cast<double>(r.mrw_inplane.size()));
    std::printf("%-22s in-plane points: RMS error %.2f um, worst %.2f um (ds/2 = %.2f um)\n",
                name.c_str(), 1e3 * rms, 1e3 * worst, 0.5e3 * ds);
    EXPECT_LE(rms, ds / std::sqrt(12.0) + 0.004) << name;
    expect_mrw_points(c, 4.0, name);
    if (overhang) return;  // the lip's underside faces down: the truth's own

    // One surface, no fold: the cupped and swollen ILM is nowhere steeper than ~65 deg, so a
    // face facing down is a marching-cubes sliver on the steepest wall tipped over by rounding;
    // measured <= 8e-6 mm2, bounded by a tenth of one grid cell (step^2 / 10 = 2.9e-5 mm2).
    // The leak of OnhRadialLeak below folded 7.2e-5 mm2 before the fallback.
    const double step = r.radial_grid_step_mm;
    EXPECT_LT(r.ilm_quality.negative_projected_area_mm2, 0.1 * step * step) << name;
}

void expect_levelset_accurate(const RadialCase& c, const std::string& name, bool overhang) {
    expect_common(c, name);
    expect_levelset_targets(c, name, overhang);
}

// The target for the level set against the device ILM on an eye without an overhang
// (where the device line is the ILM): in-plane MRW per eye within 5 um, per point within 15 um
// (the two lines meet the same BMO points; the level set's offset is 1-3 um and its per-point
// curve error up to ~2 x ds/2, docs/algorithms/levelset.md; 15 um is what the issue asks).
void expect_inplane_near_device(const OnhResult& ls, const OnhResult& dev, const std::string& name) {
    ASSERT_EQ(ls.mrw_inplane.size(), dev.mrw_inplane.size()) << name;
    double worst = 0.0;
    for (std::size_t i = 0; i < ls.mrw_inplane.size(); ++i) {
        worst = std::max(worst, std::fabs(ls.mrw_inplane[i].mrw_mm - dev.mrw_inplane[i].mrw_mm));
    }
    std::printf("%-22s in-plane MRW vs device ILM %+.2f um per eye, worst point %.2f um\n",
                name.c_str(), 1e3 * (ls.mrw_inplane_mean_mm - dev.mrw_inplane_mean_mm), 1e3 * worst);
    EXPECT_NEAR(ls.mrw_inplane_mean_mm, dev.mrw_inplane_mean_mm, 0.005) << name;
    EXPECT_LE(worst, 0.015) << name;
}

// Both eyes of one shape, 24 lines, level-set ILM (phantom and truth ~2 s, the level set
// ~1.5 s per eye in Release); one test per shape so that they run in parallel.
void levelset_both_eyes(OnhShape shape) {
    for (const io::Laterality eye : {io::Laterality::kOD, io::Laterality::kOS}) {
        const std::string name =
            "levelset " + to_string(shape) + (eye == io::Laterality::kOD ? " OD" : " OS");
        const RadialCase c = run_radial(radial_params(shape, eye), IlmSource::kLevelSet);
        print_row(name, c);
        expect_levelset_accurate(c, name, shape == OnhShape::kOverhang);
        if (shape != OnhShape::kOverhang) {
            expect_inplane_near_device(
                c.r, analyse_onh(c.ph.scan, device_ilm_surface(c.ph.scan)), name);
        } else {
            // Under the lip the level set follows the hidden wall as closely as an open one
            // (the refinement under lips, docs/algorithms/levelset.md): the 3-D MRW within
            // 2 um (the cupped disc's own error is -0.46 um, the open surfaces' offset 1-3 um)
            // and the MRW area within 1 % (2 um of the ~0.3 mm MRW is 0.7 %). With one global
            // decision level the cavity came out too large: -2.77 um and -1.67 %.
            const OnhTruth& t = c.ph.truth;
            EXPECT_NEAR(c.r.mrw_mean_mm, t.mrw_mean_mm, 0.002) << name;
            EXPECT_NEAR(c.r.mrw_area_mm2, t.mrw_area_mm2, 0.01 * t.mrw_area_mm2) << name;
        }
    }
}

// Slow: two full-size radial phantoms each.
SLOW_TEST(OnhRadialTruth, LevelSetCuppedBothEyes) { levelset_both_eyes(OnhShape::kCupped); }
// Release only (ACCURACY_TEST); under the sanitizers its code paths run in
// OnhRadialTruth.LevelSetCuppedBothEyes.
ACCURACY_TEST(OnhRadialTruth, LevelSetSwollenBothEyes) { levelset_both_eyes(OnhShape::kSwollen); }
// The overhang: the device ILM's envelope misses V_cup by -4.7 %, V_bmo by +12.7 %, the MRWs by
// +130 um and the MRW area by +65 % (OverhangWithDeviceIlmIsBlindToTheCavity); the level set
// meets every target.
// Release only (ACCURACY_TEST); under the sanitizers its code paths run in
// OnhRadialTruth.LevelSetCuppedBothEyes.
ACCURACY_TEST(OnhRadialTruth, LevelSetOverhangBothEyes) { levelset_both_eyes(OnhShape::kOverhang); }

// Slow: 12 lines (15 deg apart: 0.22 mm at the BMO), cupped and overhang.
// Release only (ACCURACY_TEST); under the sanitizers its code paths run in
// OnhRadialTruth.LevelSetCuppedBothEyes.
ACCURACY_TEST(OnhRadialTruth, LevelSetTwelveLines) {
    for (const OnhShape shape : {OnhShape::kCupped, OnhShape::kOverhang}) {
        const std::string name = "levelset " + to_string(shape) + " 12 lines";
        const RadialCase c = run_radial(radial_params(shape, io::Laterality::kOD, 0.0, 12),
                                        IlmSource::kLevelSet);
        print_row(name, c);
        expect_levelset_accurate(c, name, shape == OnhShape::kOverhang);
    }
}

// Slow (2.1-3.6 s Release on the loaded machine: a full-size 24-line phantom, its truth, the
// device ILM and one level set): the
// reproduction of issue 32's leak. The cupped eye with 60 um of axial motion (registered),
// vessel shadows and a dark cleft under the superior vessel: without the fallback the front
// runs down the cleft on the cup wall of B-scan 15 and a shadow of B-scan 14 (their top
// crossings 20-35 px below the device ILM over 15-20 A-scans), that B-scan's in-plane MRW point
// is 23 um short of the device ILM's, the 3-D MRW 21 um off the truth at one point and the mesh
// folds (7.2e-5 mm2 facing down). The leaks are found (flagged, counted): the shadow's tissue is
// cut from the vitreous (it is brighter than a quarter of the way from the vitreous to the
// tissue), the cleft's A-scans, dark to the bottom, fall back to the device ILM; then the
// issue's targets hold: level set vs device ILM in-plane MRW within 5 um per eye and 15 um per
// point, the still eye's tolerances against the truth.
SLOW_TEST(OnhRadialLeak, CleftAndShadowsFallBackToTheDeviceIlm) {
    OnhPhantomParams p = radial_params(OnhShape::kCupped);
    p.artefacts.motion_sd_um = 60.0;
    p.artefacts.vessel_shadows = true;
    p.artefacts.cleft = true;
    const OnhPhantom ph = make_onh_phantom(p);
    io::Scan scan = ph.scan;
    (void)register_axially(scan);
    const OnhResult dev = analyse_onh(scan, device_ilm_surface(scan));
    const RadialCase c{ph, analyse_onh(scan, levelset_ilm_surface(scan))};
    const OnhResult& r = c.r;
    print_row("leak phantom levelset", c);
    EXPECT_EQ(r.levelset_leak_bscans, (std::vector<int>{14, 15}));
    // The cleft: one run of at least 3 A-scans plus two on either side, at most 40 + 4; the
    // shadow's cut holds at least one 3 x 3 block; both well under a B-scan's 384 A-scans.
    EXPECT_GE(r.levelset_leak_fallback_ascans, 3 + 4);
    EXPECT_LE(r.levelset_leak_fallback_ascans, 40 + 4);
    EXPECT_GE(r.levelset_leak_cut_ascans, 3);
    EXPECT_LE(r.levelset_leak_cut_ascans, 2 * 40);
    bool flagged = false;
    for (const std::string& f : r.qc_flags) {
        flagged = flagged || f.find("level-set front leaked into the tissue in radial B-scans 14, "
                                    "15: ") == 0;
    }
    EXPECT_TRUE(flagged);
    expect_inplane_near_device(r, dev, "leak phantom levelset");
    const OnhTruth& t = c.ph.truth;
    EXPECT_NEAR(r.ellipse.area_mm2, t.bmo_area_mm2, 0.01 * t.bmo_area_mm2);
    EXPECT_NEAR(r.annular_volume_mm3, t.annular_volume_mm3, 0.02 * t.annular_volume_mm3);
    EXPECT_NEAR(r.conht_mm, t.conht_mm, 0.005);
    expect_levelset_targets(c, "leak phantom levelset", false);
}

// Without pixels, or with a B-scan that holds no image, the level set refuses (naming the
// B-scan); the device ILM analyses the same scan from its lines.
// The overhang with vessel shadows (issue 32 item 3), 12 lines (the smallest scan that shows it;
// 1.9 s CPU in Release, 2-4 s wall on the loaded machine: phantom, truth, one level set). Under the rim lip the
// front crosses from the cavity sideways into a vessel's shadow and runs down under the cup
// wall to its window's bottom: without the cut, in-plane MRW -16.2 um, 3-D MRW -14.7 um (worst
// point 116 um), MRW area -10.5 %, 0.66 mm2 facing down; the top-crossing rule cannot see it
// (the lip above is where the device line is). The shadowed tissue is brighter than the cavity
// (vitreous, darkened by the same shadow): cut, flagged and counted, the overhang's targets hold
// as on the still, clean eye, and the lip keeps its underside: 0.532 mm2 facing down on the clean
// 12-line phantom, 0.537 here; the leak had added 0.13 mm2, the bound is a sixth of that above
// the clean value, and the cut must not take the cavity itself (a fifth of it below).
// Release only (ACCURACY_TEST); under the sanitizers the cut runs in
// OnhRadialLeak.CleftAndShadowsFallBackToTheDeviceIlm.
ACCURACY_TEST(OnhRadialLeak, OverhangShadowsAreCutFromTheCavity) {
    OnhPhantomParams p = radial_params(OnhShape::kOverhang, io::Laterality::kOD, 0.0, 12);
    p.artefacts.vessel_shadows = true;
    const RadialCase c = run_radial(p, IlmSource::kLevelSet);
    const OnhResult& r = c.r;
    print_row("overhang shadows 12", c);
    EXPECT_FALSE(r.levelset_leak_bscans.empty());
    EXPECT_GE(r.levelset_leak_cut_ascans, 3);
    bool flagged = false;
    for (const std::string& f : r.qc_flags) {
        flagged = flagged || (f.find("level-set front leaked into the tissue in radial B-scan") == 0 &&
                              f.find("shadowed tissue cut from the vitreous in ") != std::string::npos);
    }
    EXPECT_TRUE(flagged);
    const OnhTruth& t = c.ph.truth;
    EXPECT_NEAR(r.ellipse.area_mm2, t.bmo_area_mm2, 0.01 * t.bmo_area_mm2);
    EXPECT_NEAR(r.annular_volume_mm3, t.annular_volume_mm3, 0.02 * t.annular_volume_mm3);
    EXPECT_NEAR(r.conht_mm, t.conht_mm, 0.005);
    expect_levelset_targets(c, "overhang shadows 12", true);
    EXPECT_LT(r.ilm_quality.negative_projected_area_mm2, 0.532 + 0.13 / 6.0);
    EXPECT_GT(r.ilm_quality.negative_projected_area_mm2, 0.8 * 0.532);
}

TEST(OnhRadial, LevelSetRefusesBscansWithoutAnImage) {
    OnhPhantomParams p = radial_params(OnhShape::kCupped, io::Laterality::kOD, 0.0, 6);
    p.num_ascans = 128;
    const io::Scan scan = render_onh_scan(p);
    io::Scan blank = scan;
    std::fill(blank.bscans[2].pixels.begin(), blank.bscans[2].pixels.end(), 0.0F);
    try {
        (void)build_ilm_surface(blank, IlmSource::kLevelSet);
        ADD_FAILURE() << "a blank B-scan was segmented";
    } catch (const AnalysisError& e) {
        EXPECT_NE(std::string(e.what()).find("radial B-scan 2"), std::string::npos) << e.what();
        // Plain, and numbered from 0 as everywhere (it said "the B-scans of radial B-scan 2
        // hold no image").
        EXPECT_NE(std::string(e.what()).find("level-set ILM: no image in radial B-scan 2 ("),
                  std::string::npos)
            << e.what();
    }
    io::Scan missing = scan;
    std::fill(missing.bscans[4].pixels.begin(), missing.bscans[4].pixels.end(), 3.4e38F);
    EXPECT_THROW((void)build_ilm_surface(missing, IlmSource::kLevelSet), AnalysisError);
    io::Scan no_pixels = scan;
    for (auto& b : no_pixels.bscans) b.pixels.clear();
    no_pixels.pixels_loaded = false;
    EXPECT_THROW((void)build_ilm_surface(no_pixels, IlmSource::kLevelSet), AnalysisError);
    EXPECT_NO_THROW((void)analyse_onh(blank, build_ilm_surface(blank, IlmSource::kDevice)));
    // A depth no radial grid can afford (128 A-scans of 34 um: ~128 x 128 nodes; x 65536 rows
    // = 1.1e9 voxels > 2^28) is refused before any work, whatever the pixels say.
    io::Scan deep = scan;
    deep.meta.size_z = 65536;
    try {
        (void)build_ilm_surface(deep, IlmSource::kLevelSet);
        ADD_FAILURE() << "a grid of 1e9 voxels was allocated";
    } catch (const AnalysisError& e) {
        EXPECT_NE(std::string(e.what()).find("radial grid would need"), std::string::npos)
            << e.what();
    }
}

}  // namespace
}  // namespace octshape::retina
