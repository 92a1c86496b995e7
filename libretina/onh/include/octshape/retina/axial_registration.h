#pragma once
// Axial registration of the B-scans of an ONH scan (volume or radial) before any surface is
// built (docs/algorithms/onh.md, "Axial registration").
//
// The eye moves along the beam between B-scans, so each B-scan's content lies a little deeper or
// shallower than its neighbours'. Bruch's membrane outside the opening is one smooth surface of
// the eye: its device line, at every A-scan's grid position p in B-scan b, is modelled as
//     depth(b, p) = o_b + S(p) + noise,   S a polynomial of degree `surface_degree` without a
// constant term, fitted with the offsets o_b by robust (Tukey) least squares; a missing BM
// value (the opening, a shadow, a gap) is simply absent. What a smooth surface can explain is
// the eye's: for a volume every B-scan has one y, so o_b absorbs any function of y, and the
// polynomial of the same degree in y fitted to the o_b is given back to the eye (a tilted,
// curved eye wall is not "registered" flat); the motion is what remains. Radial lines all pass
// through the crossing, so every function of the position is seen by several lines: only the
// mean offset is the eye's. The motion is removed from every segmentation line of each B-scan
// and from its pixels rounded to whole rows (io::shift_bscan; no rows blended, so the speckle
// and edges stay as read: the pixels lie up to half a pixel from their lines; that residual is
// kept in io::BScan::line_offset_px, and the level set moves its result by it).

#include <string>
#include <vector>

#include <Eigen/Core>

#include "octshape/io/scan.h"
#include "octshape/retina/bmo.h"
#include "octshape/retina/lateral_registration.h"

namespace octshape::retina {

struct AxialRegistrationParams {
    bool enabled = true;
    int surface_degree = 3;           // polynomial degree of the smooth BM surface (1..4)
    double large_motion_um = 20.0;    // flag when the RMS of the removed shifts exceeds this
    double max_residual_um = 15.0;    // flag when the BM is not one smooth surface
    double min_bm_fraction = 0.1;     // a B-scan with fewer BM values is not estimated
    // Volumes: the eye wall's curvature across the B-scans is taken equal to its curvature along
    // them (S's x^2 term), so that the offsets' curvature beyond it is motion; false: every
    // polynomial of surface_degree in y belongs to the eye (a curved motion is left in it).
    bool isotropic_curvature = true;
    // Flag when the curvature removed as motion, were it the eye wall's instead, would move the
    // mean 3-D MRW by more than this (um; assess_curvature_mrw_effect).
    double max_curvature_mrw_um = 5.0;

    void validate() const;  // throws UsageError naming the field
};

struct AxialRegistration {
    bool enabled = false;   // asked for
    bool applied = false;   // estimated and removed
    std::vector<double> shift_um;     // per B-scan: the motion removed (+ = the B-scan lay deeper)
    std::vector<bool> estimated;      // false: interpolated from the estimated neighbours
    double rms_shift_um = 0.0;        // of shift_um
    double max_abs_shift_um = 0.0;
    double residual_rms_um = 0.0;     // BM about the fitted model (inliers)
    int bscans_not_estimated = 0;
    int bm_values_used = 0;           // inliers of the robust fit
    int bm_values_rejected = 0;       // outliers (Tukey weight 0)
    int surface_degree = 0;
    // Volumes with isotropic_curvature: the curvature across the B-scans (um at the field's
    // first and last B-scan, against the middle) that the offsets held beyond the eye's, removed
    // with the motion (+ = the B-scans at the field's edges lay deeper).
    double curvature_to_motion_um = 0.0;
    // The field's half height h (mm; volumes): the B-scans' y run from 0 to 2h, the curvature's
    // depth is curvature_to_motion_um ((y - h) / h)^2.
    double field_half_height_mm = 0.0;
    // What that curvature would move the mean 3-D MRW by were it the eye wall's and not motion
    // (um, >= 0), from the eye's own MRW segments: set by assess_curvature_mrw_effect after the
    // ONH analysis (0 until then, and for radial scans).
    double curvature_mrw_effect_um = 0.0;
    std::vector<std::string> qc_flags;
    std::vector<std::string> notes;
};

// Estimates the motion from the scan's BM line (AxialRegistration::applied false, with a
// flag, when there is too little BM). Needs a volume or a radial scan.
[[nodiscard]] AxialRegistration estimate_axial_motion(const io::Scan& scan,
                                                      const AxialRegistrationParams& params = {});
// Removes the estimated motion from every B-scan: the lines by the shift, the pixels by the
// shift rounded to whole rows (a shift under half a row leaves them as read); adds what the
// lines moved beyond the pixels to io::BScan::line_offset_px. No-op unless applied.
void apply_axial_registration(io::Scan& scan, const AxialRegistration& registration);
// Moves BMO points given in the unregistered scan with it: each point by its B-scan's shift
// (a point from an x_mm,y_mm,z_mm file: the B-scan nearest its y).
void register_bmo_points(std::vector<BmoPoint>& points, const io::Scan& scan,
                         const AxialRegistration& registration);
// The B-scan a BMO point belongs to: its own, or (a point from an x_mm,y_mm,z_mm file) the
// B-scan nearest its y; -1 when neither.
[[nodiscard]] int bscan_of_bmo_point(const BmoPoint& point, const io::Scan& scan);
// Moves BMO points given in the unregistered scan with the lateral registration (towards lower
// A-scans by their B-scan's shift; lateral_registration.h). No-op unless applied.
void register_bmo_points_laterally(std::vector<BmoPoint>& points, const io::Scan& scan,
                                   const LateralRegistration& registration);
// The curvature's effect on the eye's mean 3-D MRW (docs/algorithms/onh.md, "Curved motion
// across B-scans"), once the MRW is measured: were the depth c(y) = curvature_to_motion_um
// ((y - h) / h)^2 removed as motion the eye wall's, each MRW segment from its BMO point P to its
// closest ILM point Q (grid mm, z = height) is sheared, to first order by v_z (c(y_Q) - c(y_P)),
// v the unit vector P -> Q; the effect is the magnitude of the mean over the points (the mean
// MRW's change: the tilt part of c cancels in it). Sets curvature_mrw_effect_um and raises the
// QC flag past params.max_curvature_mrw_um. Segments not finite or of zero length are skipped;
// no-op unless the curvature prior removed a curvature (volumes).
void assess_curvature_mrw_effect(AxialRegistration& registration,
                                 const std::vector<Eigen::Vector3d>& bmo_points_mm,
                                 const std::vector<Eigen::Vector3d>& mrw_points_mm,
                                 const AxialRegistrationParams& params = {});
// Both: estimate, then apply when params.enabled.
[[nodiscard]] AxialRegistration register_axially(io::Scan& scan,
                                                 const AxialRegistrationParams& params = {});

}  // namespace octshape::retina
