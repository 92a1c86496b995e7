#pragma once
// Lateral registration of the B-scans of a volume before any surface is built, for the ONH and
// the macula analyses alike (docs/algorithms/onh.md, "Lateral registration";
// docs/algorithms/cube.md for the macula).
//
// A tracking error moves a whole B-scan along its A-scans: B-scan b's content lies s_b A-scans
// towards higher A-scans than the eye, while the header's positions are unchanged. The eye's
// surfaces are smooth across B-scans, so the shifts are those that make the device's ILM and
// BM lines smoothest across B-scans: the second difference across B-scans of the registered
// lines, R_b(a) = D_b(a + s_b) - o_b (o_b a per-B-scan depth offset, the axial motion, a
// nuisance here), is minimised over every A-scan by robust (Tukey) Gauss-Newton least squares.
// A smooth eye cannot be told from a smooth motion: the shifts' components along the cosines
// across the B-scans with a wavelength above smooth_wavelength_mm are the eye's, constrained
// to zero. Applied only above min_rms_um (a still scan stays as read); lines by the fractional
// shift, pixels by whole A-scans. Radial scans: not estimated (the lines cross; every line's
// A-scan at the crossing is the same point).

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "octshape/io/scan.h"

namespace octshape::retina {

struct LateralRegistrationParams {
    bool enabled = true;
    double smooth_wavelength_mm = 0.75;  // shifts varying slower across B-scans: the eye's
    // The cut-off at most this many B-scans (0 = off): for dense volumes, whose modes just above a
    // cut-off of many B-scans are hardly estimable (docs/algorithms/cube.md "Lateral registration
    // (measured)"). The result's smooth_wavelength_mm is the cut-off used.
    double smooth_wavelength_bscans = 0.0;
    double min_rms_um = 5.0;         // below this RMS nothing is moved (a still eye's floor)
    double large_motion_um = 15.0;   // flag when the RMS of the shifts exceeds this
    double max_shift_se_um = 5.0;    // not estimable (nothing applied) above this median SE
    double min_line_fraction = 0.1;  // a B-scan with fewer valid ILM+BM values is not estimated
    // The lines smoothed along their A-scans by a Gaussian of this SD (A-scans) before the fit;
    // 0 = as read.
    double line_smoothing_ascans = 0.0;
    // The lines moved by the shift rounded to whole A-scans too (as the pixels always are): each
    // B-scan keeps the device's own values and their noise (false: the fractional shift,
    // linear between samples).
    bool whole_ascans = false;
    // The Gauss-Newton passes stop when the largest step falls below this (A-scans; after at
    // least 5 passes, at most 20). Lines moved by whole A-scans need far less than the default.
    double step_tolerance_ascans = 1e-4;

    void validate() const;  // throws UsageError naming the field
};

struct LateralRegistration {
    bool enabled = false;   // asked for
    bool estimable = false; // a volume with enough lines to estimate the shifts
    bool applied = false;   // estimated and removed
    std::vector<double> shift_um;   // per B-scan: + = the B-scan lay towards higher A-scans
    std::vector<bool> estimated;    // false: too few line values; its shift is set to 0
    double rms_shift_um = 0.0;
    double max_abs_shift_um = 0.0;
    double shift_se_um = 0.0;       // median standard error of one B-scan's shift
    double residual_rms_um = 0.0;   // second difference across B-scans of the registered lines
    int bscans_not_estimated = 0;
    int values_used = 0;            // line triples (b-1, b, b+1) of the robust fit, inliers
    int values_rejected = 0;        // outliers (Tukey weight 0)
    int iterations = 0;
    int smooth_modes = 0;           // cosines across B-scans given to the eye
    double smooth_wavelength_mm = 0.0;  // the cut-off they come from (after smooth_wavelength_bscans)
    bool whole_ascans = false;          // the lines too were moved by whole A-scans (params)
    std::vector<std::string> qc_flags;
    std::vector<std::string> notes;
};

// Estimates the lateral shifts from the scan's device ILM and BM lines. Needs a volume (a
// radial scan: not estimable, with a note).
[[nodiscard]] LateralRegistration estimate_lateral_motion(
    const io::Scan& scan, const LateralRegistrationParams& params = {});
// Removes the estimated shifts from every B-scan (pixels and lines). No-op unless applied.
void apply_lateral_registration(io::Scan& scan, const LateralRegistration& registration);
// (The BMO points of a --bmo file move with their B-scan: register_bmo_points_laterally,
// axial_registration.h.)
// Both: estimate, then apply when params.enabled.
[[nodiscard]] LateralRegistration register_laterally(
    io::Scan& scan, const LateralRegistrationParams& params = {});
// The per-eye JSON's "lateral_registration" object (docs/outputs.md), the same for both analyses.
[[nodiscard]] nlohmann::ordered_json lateral_registration_json(const LateralRegistration& l);

}  // namespace octshape::retina
