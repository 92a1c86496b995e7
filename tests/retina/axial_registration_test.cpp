// Acquisition artefacts of the ONH phantom and the axial registration that undoes the motion
// (issue 32; docs/phantoms.md "Acquisition artefacts", docs/algorithms/onh.md "Axial
// registration").

#include "octshape/retina/axial_registration.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <string>
#include <tuple>

#include <Eigen/Dense>
#include <gtest/gtest.h>

#include "octshape/error.h"
#include "octshape/retina/onh.h"
#include "octshape/retina/phantom_onh.h"
#include "slow_test.h"
#include "vitreous_speckle.h"

namespace octshape::retina {
namespace {

OnhPhantomParams moving(bool radial, double motion_um, int bscans, int ascans) {
    OnhPhantomParams p = onh_phantom_preset(OnhShape::kCupped);
    p.radial = radial;
    p.num_bscans = bscans;
    p.radial_lines = radial ? bscans : p.radial_lines;
    p.num_ascans = ascans;
    p.artefacts.motion_sd_um = motion_um;
    p.artefacts.vessel_shadows = motion_um > 0.0;
    p.artefacts.segmentation_faults = motion_um > 0.0;
    return p;
}

// The part of (estimated - true) shifts that the data can tell (um, RMS): a volume's B-scans
// each have one y, so a cubic in y of the motion is the eye's as far as the BM can say (the
// registration leaves it: docs/algorithms/onh.md); a radial scan's common offset likewise.
double identifiable_error_um(const AxialRegistration& reg, const OnhPhantomParams& p) {
    const std::vector<double> t = onh_acquisition_shifts(p).axial_px;
    const double um = p.scale_z_mm * 1000.0;
    const auto n = static_cast<Eigen::Index>(t.size());
    const int k = p.radial ? 1 : 4;
    Eigen::MatrixXd X(n, k);
    Eigen::VectorXd d(n);
    for (Eigen::Index b = 0; b < n; ++b) {
        const double y = -1.0 + 2.0 * static_cast<double>(b) / static_cast<double>(n - 1);
        for (int j = 0; j < k; ++j) X(b, j) = std::pow(y, j);
        d(b) = reg.shift_um[static_cast<std::size_t>(b)] - t[static_cast<std::size_t>(b)] * um;
    }
    const Eigen::VectorXd r = d - X * X.colPivHouseholderQr().solve(d);
    return std::sqrt(r.squaredNorm() / static_cast<double>(n));
}

TEST(ShiftBscan, MovesPixelsAndLinesTogether) {
    io::BScan b;
    const int nx = 3;
    const int nz = 6;
    b.pixels.assign(static_cast<std::size_t>(nx * nz), 0.0F);
    for (int z = 0; z < nz; ++z) {
        for (int a = 0; a < nx; ++a) b.pixels[static_cast<std::size_t>(z * nx + a)] = static_cast<float>(z);
    }
    b.seg = {{1.0F, 2.0F, std::numeric_limits<float>::quiet_NaN()}};
    io::shift_bscan(b, nx, nz, 1.5);
    // Row z holds what was at z - 1.5 (linear), the top rows repeat row 0.
    EXPECT_FLOAT_EQ(b.pixels[static_cast<std::size_t>(3 * nx)], 1.5F);
    EXPECT_FLOAT_EQ(b.pixels[static_cast<std::size_t>(5 * nx + 2)], 3.5F);
    EXPECT_FLOAT_EQ(b.pixels[0], 0.0F);
    EXPECT_FLOAT_EQ(b.seg[0][0], 2.5F);
    EXPECT_FLOAT_EQ(b.seg[0][1], 3.5F);
    EXPECT_TRUE(std::isnan(b.seg[0][2]));
    // Laterally: linear between present values; next to a missing one the nearer sample
    // decides presence (a gap's edge moves with the content instead of always growing) and
    // the value is the line extrapolated from the present side.
    io::BScan c;
    c.seg = {{1.0F, 2.0F, std::numeric_limits<float>::quiet_NaN()}};
    io::BScan d = c;
    io::shift_bscan(c, nx, nz, 0.0, 0.3);
    EXPECT_FLOAT_EQ(c.seg[0][1], 1.7F);
    EXPECT_TRUE(std::isnan(c.seg[0][2]));  // 2 - 0.3 = 1.7: nearer to the missing sample 2
    io::shift_bscan(d, nx, nz, 0.0, -0.3);
    EXPECT_FLOAT_EQ(d.seg[0][1], 2.3F);  // 1.3: nearer to the present sample 1, slope 1
    EXPECT_TRUE(std::isnan(d.seg[0][2]));
}

// A shift and its inverse give a line that is linear on each side of a gap (a BM up to the
// BMO) back, the gap's edges included: with the nearer sample's value instead, the values next
// to the gap were off by up to half a sample's slope, and on a 97 x 256 cupped phantom a round
// trip of half an A-scan moved the cup volume by +5 % and the CONHT by -12 um.
TEST(ShiftBscan, LateralRoundTripKeepsTheLineAtAGap) {
    const int nx = 12;
    const float nan = std::numeric_limits<float>::quiet_NaN();
    const auto left = [](int a) { return 100.0 + 2.0 * a; };   // A-scans 0..4
    const auto right = [](int a) { return 90.0 - 3.0 * a; };   // A-scans 8..11
    io::BScan b;
    b.seg = {std::vector<float>(static_cast<std::size_t>(nx))};
    for (int a = 0; a < nx; ++a) {
        b.seg[0][static_cast<std::size_t>(a)] =
            a >= 5 && a <= 7 ? nan : static_cast<float>(a < 5 ? left(a) : right(a));
    }
    for (const double dx : {0.5, -0.5, 0.3, -0.7}) {
        io::BScan c = b;
        io::shift_bscan(c, nx, 10, 0.0, dx);
        io::shift_bscan(c, nx, 10, 0.0, -dx);
        // Away from the field's edges (clamped there): every present value is its side's line
        // (to float precision), a gap's edge included; the gap moves by at most one sample.
        int present = 0;
        for (int a = 1; a + 1 < nx; ++a) {
            const float w = c.seg[0][static_cast<std::size_t>(a)];
            if (std::isnan(w)) continue;
            ++present;
            const double err = a < 5 ? std::fabs(w - left(a))
                               : a > 7 ? std::fabs(w - right(a))
                                       : std::min(std::fabs(w - left(a)), std::fabs(w - right(a)));
            EXPECT_LT(err, 1e-4) << "dx " << dx << " A-scan " << a;
        }
        EXPECT_NEAR(present, nx - 2 - 3, 1) << "dx " << dx;
    }
}

TEST(OnhPhantomAcquisition, MotionMovesTheDeviceLinesNotTheTruth) {
    const OnhPhantomParams still = moving(false, 0.0, 25, 64);
    OnhPhantomParams moved = still;
    moved.artefacts.motion_sd_um = 40.0;
    const auto shifts = onh_acquisition_shifts(moved).axial_px;
    // Exactly the asked SD (rescaled), zero mean, and the same for the same seed.
    double sum = 0.0;
    double ss = 0.0;
    for (double s : shifts) {
        sum += s;
        ss += s * s;
    }
    const double um = still.scale_z_mm * 1000.0;
    EXPECT_NEAR(sum, 0.0, 1e-9);
    EXPECT_NEAR(std::sqrt(ss / static_cast<double>(shifts.size())) * um, 40.0, 1e-9);
    EXPECT_EQ(shifts, onh_acquisition_shifts(moved).axial_px);
    const io::Scan a = render_onh_scan(still);
    const io::Scan b = render_onh_scan(moved);
    const int bm = static_cast<int>(io::Layer::kBM);
    for (int k = 0; k < a.num_bscans(); ++k) {
        for (int i = 0; i < a.meta.size_x; i += 7) {
            const float va = a.depth_px(bm, k, i);
            if (!io::is_valid(va)) continue;
            // float32 depths of ~300 px: 3e-5 px of rounding on each side.
            EXPECT_NEAR(b.depth_px(bm, k, i), va + shifts[static_cast<std::size_t>(k)], 1e-3);
        }
    }
    // The truth is the still eye's: the truth object of the file does not move.
    OnhTruthOptions fast;
    fast.phi_steps = 64;
    fast.mrw_points = 24;
    const OnhTruth t = compute_onh_truth(still, fast);
    EXPECT_EQ(onh_truth_to_json(still, fast, t)["truth"], onh_truth_to_json(moved, fast, t)["truth"]);
    EXPECT_FALSE(onh_truth_to_json(still, fast, t).contains("acquisition"));
    EXPECT_EQ(onh_truth_to_json(moved, fast, t)["acquisition"]["axial_shift_um"].size(), 25U);
    OnhPhantomParams bad = still;
    bad.artefacts.motion_sd_um = 150.0;
    EXPECT_THROW(bad.validate(), UsageError);
}

// The phantoms render the moved eye, speckle last (docs/phantoms.md, "Acquisition artefacts"):
// every B-scan of a moving acquisition has the speckle of a still one. Blending two rows or
// A-scans a fraction f apart, as the earlier phantoms did, scales the speckle's variance by
// (1 - f)^2 + f^2 (down to 0.5 at f = 1/2). Bound: 15 %, from the sampling of the variance of
// Gamma(L) values: its relative SD is sqrt((2 + 6 / L) / n), 2.4 % for L = 3 (macula) and
// n >= 6000 vitreous pixels per B-scan (64 or 96 A-scans, >= 90 rows), so 15 % is > 6 SD.
// Measured: 0.032 (volume), 0.034 (radial), 0.035 on the still volume; the earlier phantoms
// 632 and 0.50 (the volume's shifted edge rows and A-scans also repeated tissue into the
// vitreous). ONH volume (motion and jitter) and radial (motion); the macula (measured 0.034,
// earlier 17): MaculaPhantomAcquisition.MovedBscansKeepTheStillSpeckle.
TEST(OnhPhantomAcquisition, MovedBscansKeepTheStillSpeckle) {
    OnhPhantomParams volume = moving(false, 60.0, 25, 64);
    volume.artefacts.vessel_shadows = false;  // the vitreous only
    volume.artefacts.lateral_jitter_um = 30.0;
    OnhPhantomParams radial = moving(true, 60.0, 12, 64);
    radial.artefacts.vessel_shadows = false;
    const int ilm = static_cast<int>(io::Layer::kILM);
    EXPECT_LT(test::worst_vitreous_speckle(render_onh_scan(volume), ilm, volume.speckle_looks), 0.15);
    EXPECT_LT(test::worst_vitreous_speckle(render_onh_scan(radial), ilm, radial.speckle_looks), 0.15);
}

// Vessels shadow the tissue below them; the device lines and the vitreous stay as they were.
TEST(OnhPhantomAcquisition, VesselShadowsDarkenTheTissueNotTheLines) {
    const OnhPhantomParams still = moving(false, 0.0, 25, 64);
    OnhPhantomParams shaded = still;
    shaded.artefacts.vessel_shadows = true;
    const io::Scan a = render_onh_scan(still);
    const io::Scan b = render_onh_scan(shaded);
    const int nx = a.meta.size_x;
    const int ilm = static_cast<int>(io::Layer::kILM);
    int shadowed = 0;
    for (int k = 0; k < a.num_bscans(); ++k) {
        const auto& pa = a.bscans[static_cast<std::size_t>(k)].pixels;
        const auto& pb = b.bscans[static_cast<std::size_t>(k)].pixels;
        for (int line : {ilm, static_cast<int>(io::Layer::kBM)}) {
            for (int i = 0; i < nx; ++i) {
                const float va = a.depth_px(line, k, i);
                const float vb = b.depth_px(line, k, i);
                EXPECT_TRUE(va == vb || (std::isnan(va) && std::isnan(vb))) << k << " " << i;
            }
        }
        for (int i = 0; i < nx; ++i) {
            const int top = static_cast<int>(std::floor(a.depth_px(ilm, k, i)));
            for (int z = 0; z < top; ++z) {  // the vitreous: untouched (same speckle seed)
                const auto at = static_cast<std::size_t>(z * nx + i);
                ASSERT_EQ(pa[at], pb[at]) << k << " " << i << " " << z;
            }
            // 0.15 mm below the ILM: at most 15 % left on a vessel's axis.
            double sa = 0.0;
            double sb = 0.0;
            for (int z = top + 40; z < top + 60; ++z) {
                const auto at = static_cast<std::size_t>(z * nx + i);
                sa += pa[at];
                sb += pb[at];
            }
            if (sb < 0.5 * sa) ++shadowed;
        }
    }
    EXPECT_GT(shadowed, 10);  // eight vessels, 60-150 um wide, cross the 25 B-scans
}

// A still eye with a curved (R = 12 mm), tilted (0.03, -0.02) wall: nothing to remove. The
// device BM is the phantom's exact quadratic in float32 (rounding 2e-5 px = 1e-4 um), inside
// the cubic model: every shift within 0.01 um of zero.
TEST(AxialRegistration, StillCurvedTiltedEyeIsNotFlattened) {
    const io::Scan scan = render_onh_scan(moving(false, 0.0, 25, 96));
    const AxialRegistration r = estimate_axial_motion(scan);
    ASSERT_EQ(r.shift_um.size(), 25U);
    EXPECT_LT(r.max_abs_shift_um, 0.01);
    EXPECT_LT(r.residual_rms_um, 0.01);
    EXPECT_LT(std::fabs(r.curvature_to_motion_um), 0.01);  // the sphere's curvature is isotropic
    EXPECT_TRUE(r.qc_flags.empty());
    // Applied, the pixels stay as read byte for byte (every shift is far under half a row).
    io::Scan registered = scan;
    apply_axial_registration(registered, r);
    for (int b = 0; b < scan.num_bscans(); ++b) {
        const auto bi = static_cast<std::size_t>(b);
        EXPECT_EQ(registered.bscans[bi].pixels, scan.bscans[bi].pixels) << "B-scan " << b;
    }
}

// 60 um of motion with vessel shadows, an ILM spike and a BM gap: the identifiable motion is
// recovered to the float32 rounding of the lines (< 0.01 um); the large-motion flag is raised.
TEST(AxialRegistration, RecoversTheMotionOfAVolume) {
    const OnhPhantomParams p = moving(false, 60.0, 25, 96);
    io::Scan scan = render_onh_scan(p);
    const AxialRegistration r = register_axially(scan);
    EXPECT_TRUE(r.applied);
    EXPECT_LT(identifiable_error_um(r, p), 0.01);
    EXPECT_LT(r.residual_rms_um, 0.01);
    EXPECT_EQ(r.bscans_not_estimated, 0);
    ASSERT_EQ(r.qc_flags.size(), 1U);
    EXPECT_EQ(r.qc_flags[0], "large axial motion between B-scans (registered)");
}

// A motion curved across the B-scans (deeper by a y^2 at the field's first and last B-scan, y
// from -1 to +1) is a smooth function of y like the eye wall's own curvature, so a free fit gives
// it to the eye; left there it is a shear z + a y^2 of the eye, under which the 3-D MRW changes
// by -v_z (c(y_Q) - c(y_P)) per point (v the unit vector from the BMO point P to its closest ILM
// point Q, heights up, c a depth): +0.0203 um per um of a on the full-size disc (bench
// onh_motion --axial-leave on 97 x 256, the truth's vectors to first order: -4.34 um for
// a = -214 um, measured -4.3). The eye wall is taken as
// isotropic: its curvature across the B-scans is its curvature along them, the BM's x^2 term.
// The phantom's wall is a sphere (R = 12 mm) and its device BM the exact quadratic in float32,
// so the prior is exact here: the curvature is removed with the motion to the lines' rounding
// (0.01 um, as the still eye above), and the registered device lines are the still ones, so
// the device-ILM 3-D MRW is the still scan's within 0.05 um (the lines' float32 rounding moved
// through the surfaces; with the curvature left in the eye, as before the prior, it is +2.6 um).
// The still scan's lines moved deeper by a_um y^2 (y from -1 at the first B-scan to +1 at the
// last): a curved motion, or as the BM sees it, a wall a_um more curved across the B-scans.
io::Scan curved_across(const io::Scan& still, double a_um) {
    const double um = still.meta.scale_z_mm * 1000.0;
    io::Scan scan = still;
    const int nb = scan.num_bscans();
    for (int b = 0; b < nb; ++b) {
        const double y = -1.0 + 2.0 * b / (nb - 1.0);
        io::BScan& bs = scan.bscans[static_cast<std::size_t>(b)];
        std::vector<float> pixels;
        pixels.swap(bs.pixels);  // the lines alone: the registration and the device ILM read them
        io::shift_bscan(bs, scan.meta.size_x, scan.meta.size_z, a_um * y * y / um);
        pixels.swap(bs.pixels);
    }
    return scan;
}

const char* const kCurvatureFlag =
    "eye wall curves differently across and along the B-scans: curvature removed as motion may "
    "be the eye's (3-D MRW uncertain by about ";

bool has_curvature_flag(const AxialRegistration& r) {
    return std::any_of(r.qc_flags.begin(), r.qc_flags.end(), [](const std::string& f) {
        return f.rfind(kCurvatureFlag, 0) == 0;
    });
}

TEST(AxialRegistration, CurvedMotionAcrossBscansIsNotGivenToTheEye) {
    const OnhPhantomParams p = moving(false, 0.0, 25, 96);
    const io::Scan still = render_onh_scan(p);
    const double a_um = 150.0;
    io::Scan scan = curved_across(still, a_um);
    const int nb = scan.num_bscans();
    const AxialRegistration r = register_axially(scan);
    ASSERT_TRUE(r.applied);
    EXPECT_NEAR(r.curvature_to_motion_um, a_um, 0.01);
    EXPECT_EQ(r.curvature_mrw_effect_um, 0.0);  // until the MRW is measured
    // The shifts are the curvature up to the eye's 1, y, y^3 (a depth, a tilt and a cubic across
    // the B-scans stay the eye's; weighted by each B-scan's BM count, which the disc makes
    // uneven in y, the fit of those three moves a little of a y^2 into them: 0.4 um here).
    Eigen::MatrixXd X(nb, 3);
    Eigen::VectorXd d(nb);
    for (int b = 0; b < nb; ++b) {
        const double y = -1.0 + 2.0 * b / (nb - 1.0);
        X.row(b) << 1.0, y, y * y * y;
        d(b) = r.shift_um[static_cast<std::size_t>(b)] - a_um * y * y;
    }
    const Eigen::VectorXd off = d - X * X.colPivHouseholderQr().solve(d);
    EXPECT_LT(off.cwiseAbs().maxCoeff(), 0.01);
    const OnhResult got = analyse_onh(scan, device_ilm_surface(scan));
    const OnhResult want = analyse_onh(still, device_ilm_surface(still));
    EXPECT_NEAR(1e3 * got.mrw_mean_mm, 1e3 * want.mrw_mean_mm, 0.05);
    // 150 um is within what a moving eye leaves (median 101 um at 100 um SD): its effect on
    // this eye's MRW, 3.3 um (keeping the curvature in the eye moves it by 2.6 um on this
    // coarse volume: see the test below), under the 5 um bound, is reported and not flagged.
    AxialRegistration assessed = r;
    assess_curvature_mrw_effect(assessed, got.ellipse.points_mm, got.mrw_points_mm);
    EXPECT_GT(assessed.curvature_mrw_effect_um, 0.0);
    EXPECT_LT(assessed.curvature_mrw_effect_um, 5.0);
    EXPECT_FALSE(has_curvature_flag(assessed));
    // Without the prior (every cubic in y the eye's) nothing of the curvature is removed.
    AxialRegistrationParams free;
    free.isotropic_curvature = false;
    const AxialRegistration f = estimate_axial_motion(scan, free);
    EXPECT_LT(f.max_abs_shift_um, 0.01);
    EXPECT_EQ(f.curvature_to_motion_um, 0.0);
}

// A still eye whose lines lie a_um y^2 deeper, registered and analysed (device ILM, 49 x 96):
// the registration, the eye's assessed curvature effect, and the MRW change measured by keeping
// the curvature in the eye (um).
struct CurvedWall {
    io::Scan kept;
    AxialRegistration r;
    OnhResult got;
    double moved_um = 0.0;
};
CurvedWall curved_wall(OnhShape shape, double a_um) {
    OnhPhantomParams p = moving(false, 0.0, 49, 96);
    const OnhPhantomParams preset = onh_phantom_preset(shape);
    p.shape = preset.shape;
    p.profile = preset.profile;
    CurvedWall w;
    w.kept = curved_across(render_onh_scan(p), a_um);
    io::Scan scan = w.kept;
    w.r = register_axially(scan);
    EXPECT_NEAR(w.r.curvature_to_motion_um, a_um, 0.01);
    EXPECT_FALSE(has_curvature_flag(w.r));  // not before the MRW is measured
    w.got = analyse_onh(scan, device_ilm_surface(scan));
    assess_curvature_mrw_effect(w.r, w.got.ellipse.points_mm, w.got.mrw_points_mm);
    w.moved_um = 1e3 * std::fabs(analyse_onh(w.kept, device_ilm_surface(w.kept)).mrw_mean_mm -
                                 w.got.mrw_mean_mm);
    std::printf("curvature %.0f um: MRW moved %.2f um, assessed %.2f um\n", a_um, w.moved_um,
                w.r.curvature_mrw_effect_um);
    return w;
}


// A still eye whose wall is 400 um more curved across the B-scans than along them at the field's
// edge (a staphyloma; to the BM the same as the curved motion above): 2 x 400 / 2.175^2 =
// 169 um/mm^2 on the 4.35 mm field. Were it the wall's, this eye's 3-D MRW moves by what
// keeping it in the eye moves it by: measured 7.9 um here, assessed from the eye's own MRW
// segments 8.3 um (the old disc-wide constant of 0.048 um per um/mm^2 said 8.1, whatever the
// disc): past the 5 um bound, so it is flagged, with the eye's number. TOL: the assessment is
// first order in the shear with P and Q following the wall; on a volume the ellipse's heights
// between the B-scans holding BMO points, and the ILM mesh between B-scans, follow it only as
// chords: the measured change approaches the first-order one as the B-scans close in (150 um
// on 25 x 96 / 49 x 192 over 4.35 mm: 2.60 / 2.88 um against 3.27 / 3.07 um; -214 um on 97 x 256:
// -4.3 um against -4.34 from the truth's P, Q), so on 49 B-scans (91 um apart) the assessment
// is within 10 % of the change (here +6 %) and errs high (the safe side for a flag).
TEST(AxialRegistration, WallCurvedMoreAcrossThanAlongIsFlagged) {
    const CurvedWall w = curved_wall(OnhShape::kCupped, 400.0);
    const AxialRegistration& r = w.r;
    EXPECT_GE(r.curvature_mrw_effect_um, w.moved_um);
    EXPECT_LE(r.curvature_mrw_effect_um, 1.1 * w.moved_um);
    ASSERT_TRUE(has_curvature_flag(r));
    char number[32];
    std::snprintf(number, sizeof number, "%.0f um)", r.curvature_mrw_effect_um);
    EXPECT_NE(std::find(r.qc_flags.begin(), r.qc_flags.end(), std::string(kCurvatureFlag) + number),
              r.qc_flags.end());
    // Without the prior nothing is removed, nothing assessed, nothing flagged.
    AxialRegistrationParams free;
    free.isotropic_curvature = false;
    AxialRegistration f = estimate_axial_motion(w.kept, free);
    assess_curvature_mrw_effect(f, w.got.ellipse.points_mm, w.got.mrw_points_mm, free);
    EXPECT_EQ(f.curvature_mrw_effect_um, 0.0);
    EXPECT_FALSE(has_curvature_flag(f));
}

// The effect is the disc's: the swollen disc's MRW segments are steeper and longer, so 200 um of
// y^2 (84.6 um/mm^2), which the cupped disc's 0.048 um per um/mm^2 (the old disc-wide constant)
// put at 4.1 um, under the 5 um bound, moves its MRW by 8.6 um (measured by keeping it in the
// eye): its own segments say 6.8 um, and it is flagged. The first order is low here by the
// second order the closest point's re-selection adds (it only shortens the sheared eye's MRW,
// a minimum; on these long segments -21 %): docs/algorithms/onh.md.
TEST(AxialRegistration, CurvatureEffectIsTheDiscsOwn) {
    const CurvedWall w = curved_wall(OnhShape::kSwollen, 200.0);
    const double constant_um = 0.048 * 2.0 * 200.0 / (2.175 * 2.175);
    EXPECT_LT(constant_um, 5.0);
    EXPECT_GT(w.moved_um, 5.0);
    EXPECT_GT(w.r.curvature_mrw_effect_um, 5.0);
    EXPECT_LE(w.r.curvature_mrw_effect_um, w.moved_um);
    EXPECT_TRUE(has_curvature_flag(w.r));
}


// With segmentation noise of sigma = 1 px (3.9 um, independent per A-scan) on the BM line, each
// B-scan's offset is a mean over its n BM values: error sigma / sqrt(n), n >= 60 here (96 A-scans,
// the opening takes <= 36), i.e. <= 0.50 um per B-scan; Tukey's weights cost ~5 % efficiency and
// the surface terms a little more: the RMS over the B-scans stays below 1.5 x 0.50 = 0.75 um
// (measured: 0.36 um).
TEST(AxialRegistration, SegmentationNoiseCostsSigmaOverRootN) {
    const OnhPhantomParams p = moving(false, 60.0, 25, 96);
    io::Scan scan = render_onh_scan(p);
    phantom::Rng rng(7);
    for (auto& b : scan.bscans) {
        for (float& v : b.seg[static_cast<std::size_t>(io::Layer::kBM)]) {
            if (io::is_valid(v)) v += static_cast<float>(rng.normal());
        }
    }
    const AxialRegistration r = estimate_axial_motion(scan);
    EXPECT_LT(identifiable_error_um(r, p), 0.75);
    // The noise itself is the BM's residual about the model: 3.87 um, its sampling error over
    // ~2,000 values ~2 %, minus the ~1 % the fitted terms absorb: 0.2 um is > 3 sigma.
    EXPECT_NEAR(r.residual_rms_um, 3.87, 0.2);
}

// Radial lines share the crossing: every shift is identifiable but the common one.
TEST(AxialRegistration, RecoversTheMotionOfRadialLines) {
    const OnhPhantomParams p = moving(true, 60.0, 12, 128);
    io::Scan scan = render_onh_scan(p);
    const io::Scan read = scan;
    const AxialRegistration r = register_axially(scan);
    EXPECT_LT(identifiable_error_um(r, p), 0.01);
    // Registered, the BM of every line lies on one smooth surface again: a second estimate
    // finds nothing left to remove.
    const AxialRegistration again = estimate_axial_motion(scan);
    EXPECT_LT(again.max_abs_shift_um, 0.01);
    // The lines move by the whole shift, the pixels by whole rows: every registered row is a
    // row as read (edge rows repeated), so the speckle and edges are unchanged. Interpolated
    // pixels would fail at every B-scan with a fractional part (checked to exist below).
    const int nx = scan.meta.size_x;
    const int nz = scan.meta.size_z;
    int fractional = 0;
    for (int b = 0; b < scan.num_bscans(); ++b) {
        const auto bi = static_cast<std::size_t>(b);
        const double dz = -r.shift_um[bi] / (scan.meta.scale_z_mm * 1000.0);
        const auto whole = static_cast<int>(std::lround(dz));
        if (std::fabs(dz - whole) > 0.1) ++fractional;
        const auto& out = scan.bscans[bi].pixels;
        const auto& in = read.bscans[bi].pixels;
        ASSERT_EQ(out.size(), in.size());
        for (int z = 0; z < nz; ++z) {
            const int src = std::clamp(z - whole, 0, nz - 1);
            for (int a = 0; a < nx; ++a) {
                ASSERT_EQ(out[static_cast<std::size_t>(z * nx + a)], in[static_cast<std::size_t>(src * nx + a)])
                    << "B-scan " << b << " row " << z << " A-scan " << a;
            }
        }
        const auto& bm = scan.bscans[bi].seg[static_cast<std::size_t>(io::Layer::kBM)];
        const auto& bm_read = read.bscans[bi].seg[static_cast<std::size_t>(io::Layer::kBM)];
        for (int a = 0; a < nx; ++a) {
            const auto ai = static_cast<std::size_t>(a);
            if (std::isfinite(bm_read[ai])) {
                EXPECT_NEAR(bm[ai], bm_read[ai] + dz, 1e-4);
            }
        }
    }
    EXPECT_GE(fractional, 6);  // 60 um SD of 3.87 um pixels: the fractional parts are uniform
}

// A user's BMO points move with their B-scan (a point of an x_mm,y_mm,z_mm file: the B-scan
// nearest its y); nothing moves when the registration was not applied.
TEST(AxialRegistration, BmoPointsMoveWithTheirBscan) {
    io::Scan scan;
    scan.meta.distance_mm = 0.1;
    AxialRegistration r;
    r.applied = true;
    r.shift_um = {0.0, 20.0, -10.0};
    std::vector<BmoPoint> pts(3);
    pts[0].bscan = 1;
    pts[0].mm = {1.0, 0.1, -1.0};
    pts[1].bscan = -1;  // from a file: y = 0.21 mm is nearest B-scan 2
    pts[1].mm = {1.0, 0.21, -1.0};
    pts[2].bscan = 7;  // not a B-scan of the scan: left alone
    pts[2].mm = {1.0, 0.0, -1.0};
    register_bmo_points(pts, scan, r);
    EXPECT_DOUBLE_EQ(pts[0].mm.z(), -1.0 + 0.020);  // 20 um deeper before: 20 um up now
    EXPECT_DOUBLE_EQ(pts[1].mm.z(), -1.0 - 0.010);
    EXPECT_DOUBLE_EQ(pts[2].mm.z(), -1.0);
    r.applied = false;
    register_bmo_points(pts, scan, r);
    EXPECT_DOUBLE_EQ(pts[0].mm.z(), -1.0 + 0.020);
}

TEST(AxialRegistration, WithoutBmNothingMovesAndAFlagSaysSo) {
    io::Scan scan = render_onh_scan(moving(false, 30.0, 25, 64));
    for (auto& b : scan.bscans) {
        for (float& v : b.seg[static_cast<std::size_t>(io::Layer::kBM)]) {
            v = std::numeric_limits<float>::quiet_NaN();
        }
    }
    const io::Scan before = scan;
    const AxialRegistration r = register_axially(scan);
    EXPECT_FALSE(r.applied);
    ASSERT_EQ(r.qc_flags.size(), 1U);
    EXPECT_EQ(r.qc_flags[0], "axial motion not estimated (too little BM)");
    EXPECT_EQ(scan.bscans[3].pixels, before.bscans[3].pixels);
    AxialRegistrationParams bad;
    bad.surface_degree = 0;
    EXPECT_THROW(bad.validate(), UsageError);
}


// ---- Full-size moving, shadowed phantoms against the still eye's truth (label "slow") -------

// The still phantoms' tolerances (tests/retina/onh_test.cpp, onh_radial_test.cpp): BMO area
// 1 %, volumes 2 %, MRW (3-D and in-plane) 5 um mean, MRW area 2 %, CONHT 5 um. Registered, the
// moving eye is the still eye up to the unidentifiable smooth drift (a cubic in y for a volume,
// nothing for a radial scan), under which every parameter is a height above the RPE or a
// distance near it: the still tolerances hold unchanged.
void expect_still_tolerances(const OnhResult& r, const OnhTruth& t, const std::string& name) {
    EXPECT_NEAR(r.ellipse.area_mm2, t.bmo_area_mm2, 0.01 * t.bmo_area_mm2) << name;
    EXPECT_NEAR(r.conht_mm, t.conht_mm, 0.005) << name;
    EXPECT_NEAR(r.mrw_mean_mm, t.mrw_mean_mm, 0.005) << name;
    EXPECT_NEAR(r.mrw_area_mm2, t.mrw_area_mm2, 0.02 * t.mrw_area_mm2) << name;
    for (const auto& [label, value, truth] :
         {std::tuple{"cup", r.cup_volume_mm3, t.cup_volume_mm3},
          std::tuple{"bmo", r.bmo_volume_mm3, t.bmo_volume_mm3},
          std::tuple{"total", r.total_volume_mm3, t.total_volume_mm3},
          std::tuple{"annular", r.annular_volume_mm3, t.annular_volume_mm3}}) {
        EXPECT_NEAR(value, truth, 0.02 * truth) << name << " " << label;
    }
    if (t.has_inplane) {
        EXPECT_NEAR(r.mrw_inplane_mean_mm, t.inplane.mean_mm, 0.005) << name;
    }
}

// Slow: full-size 24-line radial phantoms (render ~1 s each) at 30 and 60 um: device ILM
// without and with registration, and the level set with it at 60 um (~0.3 + 0.3 + 3 s).
SLOW_TEST(OnhMovingPhantom, RadialThirtyAndSixtyMicronsWithShadowsMeetTheStillTolerances) {
    for (const double sd : {30.0, 60.0}) {
        const OnhPhantomParams p = moving(true, sd, 24, 384);
        const OnhTruth t = compute_onh_truth(p);
        const io::Scan raw = render_onh_scan(p);
        const std::string name = "radial " + std::to_string(static_cast<int>(sd)) + " um ";
        {
            // Unregistered, the 3-D quantities break (the failure): CONHT by far more
            // than its 5 um (bench onh_motion: +40 um at 30 um, +81 um at 60; the ILM and the
            // RPE at the crossing come from different lines' depths). (The MRW area, +4.9 % and
            // +14.8 % there, broke mostly through the BMO heights' steps between lines; with
            // the heights linear in angle it is +1.1 % at 30 um: docs/algorithms/onh.md
            // "3-D MRW per point".)
            const OnhResult r = analyse_onh(raw, device_ilm_surface(raw));
            std::printf("%sunregistered: CONHT %+.1f um, MRW area %+.2f %%\n", name.c_str(),
                        1e3 * (r.conht_mm - t.conht_mm), 100.0 * (r.mrw_area_mm2 / t.mrw_area_mm2 - 1.0));
            EXPECT_GT(std::fabs(r.conht_mm - t.conht_mm), 0.02) << name;
        }
        io::Scan scan = raw;
        const AxialRegistration reg = register_axially(scan);
        EXPECT_LT(identifiable_error_um(reg, p), 0.01) << name;
        expect_still_tolerances(analyse_onh(scan, device_ilm_surface(scan)), t, name + "device");
        if (sd == 60.0) {
            expect_still_tolerances(analyse_onh(scan, levelset_ilm_surface(scan)), t,
                                    name + "levelset");
        }
    }
}

// Slow: a full-size volume (145 x 384 x 496, render ~3 s), 60 um of motion, device ILM without
// and with registration (~0.3 s each).
SLOW_TEST(OnhMovingPhantom, VolumeSixtyMicronsWithShadowsMeetsTheStillTolerances) {
    const OnhPhantomParams p = moving(false, 60.0, 145, 384);
    const OnhTruth t = compute_onh_truth(p);
    const io::Scan raw = render_onh_scan(p);
    {
        // Unregistered: the MRW area off by more than its 2 % (bench: +5.1 % with the BMO
        // heights of the nearest measured point; +3.3 % with them linear in angle, which
        // removed their steps between B-scans: docs/algorithms/onh.md "3-D MRW per point").
        const OnhResult r = analyse_onh(raw, device_ilm_surface(raw));
        std::printf("volume 60 um unregistered: MRW area %+.2f %%, 3-D MRW %+.2f um\n",
                    100.0 * (r.mrw_area_mm2 / t.mrw_area_mm2 - 1.0), 1e3 * (r.mrw_mean_mm - t.mrw_mean_mm));
        EXPECT_GT(std::fabs(r.mrw_area_mm2 / t.mrw_area_mm2 - 1.0), 0.02);
    }
    io::Scan scan = raw;
    const AxialRegistration reg = register_axially(scan);
    EXPECT_LT(identifiable_error_um(reg, p), 0.01);
    expect_still_tolerances(analyse_onh(scan, device_ilm_surface(scan)), t, "volume device");
}

}  // namespace
}  // namespace octshape::retina
