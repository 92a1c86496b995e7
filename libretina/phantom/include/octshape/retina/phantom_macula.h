#pragma once
// Synthetic Spectralis macula scans whose true CuBe parameters (docs/algorithms/cube.md,
// thesis §7.3) are known
// independently of the analysis code (docs/phantoms.md, "Macula phantoms").
//
// The retinal thickness is a surface T(r, theta) in polar coordinates about the true fovea
// centre, theta anatomical (0 deg nasal, 90 deg superior, both eyes). Two families:
//  * Bezier: per direction an interior cubic Bezier exactly of the CuBe form (Eq. 7.5, 7.7)
//    and an exterior cubic with a horizontal tangent at the rim (Eq. 7.6, 7.11) running to
//    r = 7 mm, beyond every corner of the field; the model represents it exactly.
//  * Scheibe: f(r) = CFT + sigma^2 u e^-u + a (1 - e^-u), u = mu r^gamma (Scheibe et al., the
//    thesis' ref. [86]); the CuBe model cannot represent it exactly.
// Parameters vary smoothly with theta (low-order Fourier terms). BM height = a paraboloid eye
// wall plus a tilt; ILM = BM + T. The frame comes from phantom_common (not ScanGeometry).

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include "octshape/io/scan.h"
#include "octshape/retina/phantom_common.h"

namespace octshape::retina {

enum class MaculaFamily { kBezier, kScheibe };

[[nodiscard]] std::string to_string(MaculaFamily f);

struct MaculaPhantomParams {
    MaculaFamily family = MaculaFamily::kBezier;
    bool flat = false;      // flat-bottomed pits (Bezier: large alpha; Scheibe: large gamma)
    io::Laterality eye = io::Laterality::kOD;
    bool line = false;      // one horizontal B-scan through the fovea (ScanPattern 1)
    // Radial scan (ScanPattern 5): radial_lines B-scans of line_length_mm through one point
    // (the crossing), 180 / radial_lines deg apart, line k at k * 180 / radial_lines deg from
    // SLO +x towards superior; size_x A-scans per line. The crossing is the centre of the
    // field; fovea_dx_mm / fovea_dy_mm are then the true fovea minus the crossing (the crossing
    // offset). The truth frame is the grid of a square field of side line_length_mm centred on
    // the crossing (x = SLO +x, y = superior), docs/phantoms.md.
    bool radial = false;
    int radial_lines = 12;
    double line_length_mm = 6.0;
    // Volume only: vertical B-scans (phantom_common.h, VolumeLayout::vertical): the same eye
    // scanned with the grid turned; the field is then size_x A-scans high, num_bscans wide.
    bool vertical = false;
    int num_bscans = 61;    // volume only
    int size_x = 768;       // A-scans per B-scan
    int size_z = 496;       // pixels per A-scan
    // 0 = keep the 25 x 30 deg field: ScaleX = 8.96623 mm / (size_x - 1) (0.01169 mm for 768).
    double scale_x_mm = 0.0;
    // 0 = keep the 7.5 mm field: Distance = 7.5 mm / (num_bscans - 1) (0.125 mm for 61).
    double distance_mm = 0.0;
    double scale_z_mm = 0.0038717;
    // True fovea centre minus the scan centre, grid mm (a line scan passes through the fovea,
    // so fovea_dy_mm must be 0 there).
    double fovea_dx_mm = 0.0;
    double fovea_dy_mm = 0.0;
    // Device thickness-grid centre minus the true fovea centre, grid mm (a hint).
    double grid_hint_dx_mm = 0.04;
    double grid_hint_dy_mm = -0.03;
    // Eye wall as it appears in OCT images (paraboloid z = -rho^2 / (2 R) about the scan
    // centre). The scan pivots near the pupil, which flattens the 12 mm eye radius; 40 mm gives
    // a realistic 0.25 mm sag across a B-scan. 0 = flat.
    double wall_radius_mm = 40.0;
    double tilt_x = 0.02;   // BM slope along grid x (mm/mm)
    double tilt_y = -0.01;  // BM slope along grid y (mm/mm)
    double noise_um = 0.0;  // Gaussian segmentation noise (SD, um) on ILM and BM, independent
    double missing_fraction = 0.0;  // fraction of A-scans whose ILM and BM are missing
    int vessels = 0;        // vessel-like bands raising the ILM by a few um (and shadowing)
    // Per-eye shape variation (cohort phantoms): the thickness profile T becomes
    // T' = T + thickness_offset_mm + (pit_depth_scale - 1) (T - kShapeReferenceMm), an affine
    // map of the height that keeps every profile exactly of its family (a cubic Bezier stays
    // one, with the same x control points; a Scheibe profile changes CFT, sigma^2 and a).
    // The offset moves CFT and rim height alike (pit depth, slopes, diameters unchanged); the
    // scale multiplies the pit depth (and changes slopes and the pit-flat disk).
    double thickness_offset_mm = 0.0;  // within +-0.1 mm
    // The eye rotated about the fovea against the scan grid (head tilt / cyclotorsion between
    // re-scans), anatomical degrees (from nasal towards superior): the profile seen at
    // anatomical angle theta is the eye's profile at theta - rotation_deg. Within +-45.
    double rotation_deg = 0.0;
    // Every radius of the profile (rim, alpha, beta, the exterior's inner control points)
    // multiplied by this factor: a wider or narrower pit of the same family (the Bezier exterior
    // still ends at 7 mm; Scheibe: mu / k^gamma). In [0.7, 1.3].
    double radial_scale = 1.0;
    double pit_depth_scale = 1.0;      // in [0.5, 1.5]
    // What the acquisition adds (docs/phantoms.md, "Acquisition artefacts"); the truth is the
    // still eye's. Its vessel shadows are three 60-150 um vessels of their own (the `vessels`
    // bands above belong to the eye: they raise the ILM).
    phantom::AcquisitionArtefacts artefacts;
    bool pixels = true;     // false: B-scan pixels are io::kNoPixelData
    std::uint64_t seed = 1;
    phantom::SpeckleParams speckle;
    // Throws UsageError naming the bad field.
    void validate() const;
};

// The analysis settings the truth is computed for (the defaults of docs/algorithms/cube.md).
struct MaculaTruthOptions {
    int num_half_lines = 24;       // n, even
    double radius_mm = 2.0;        // R
    double tau_mm = 0.005;         // pit-flat threshold
    double inner_radius_mm = 0.5;  // r_u
    int quadrature_panels = 256;   // Scheibe volumes: Gauss-Legendre panels (then doubled)
    void validate() const;
};

// One direction's Bezier profile (radius r along x, thickness along y; mm).
struct BezierProfile {
    double cft_mm = 0.0;
    double rim_radius_mm = 0.0;  // w = P3.x of the interior
    double rim_height_mm = 0.0;
    double alpha_mm = 0.0;       // interior P1 = P0 + alpha (1, 0)
    double beta_mm = 0.0;        // interior P2 = P3 - beta (1, 0)
    double alpha_ext_mm = 0.0;   // exterior P1 = P0 + alpha_ext (1, 0)
    Eigen::Vector2d ext_p2 = Eigen::Vector2d::Zero();
    Eigen::Vector2d ext_p3 = Eigen::Vector2d::Zero();
    [[nodiscard]] std::array<Eigen::Vector2d, 4> interior() const;
    [[nodiscard]] std::array<Eigen::Vector2d, 4> exterior() const;
};

// One direction's Scheibe profile.
struct ScheibeProfile {
    double cft_mm = 0.0;
    double sigma2_mm = 0.0;  // sigma^2
    double a_mm = 0.0;       // far-field increase over CFT (the model's alpha)
    double mu = 0.0;         // per mm^gamma
    double gamma = 2.0;
    [[nodiscard]] double thickness_mm(double r_mm) const;
    [[nodiscard]] double slope(double r_mm) const;      // dT/dr
    [[nodiscard]] double curvature(double r_mm) const;  // d2T/dr2
    // Closed form: u* = 1 + a / sigma^2, r* = (u*/mu)^(1/gamma).
    [[nodiscard]] double rim_radius_mm() const;
};

[[nodiscard]] BezierProfile bezier_profile(double theta_deg, bool flat);
[[nodiscard]] ScheibeProfile scheibe_profile(double theta_deg, bool flat);

// The height about which pit_depth_scale scales (the Bezier profiles' mean rim height, mm).
inline constexpr double kShapeReferenceMm = 0.350;
// The profiles of `p` in direction theta with p's shape variation applied.
[[nodiscard]] BezierProfile bezier_profile(double theta_deg, const MaculaPhantomParams& p);
[[nodiscard]] ScheibeProfile scheibe_profile(double theta_deg, const MaculaPhantomParams& p);

// Largest radius the exterior Bezier reaches (thickness is defined up to here).
inline constexpr double kBezierEndRadiusMm = 7.0;

// Thickness T(r, theta) of the generating surface, mm (without vessels and noise).
[[nodiscard]] double macula_thickness_mm(const MaculaPhantomParams& p,
                                         double r_mm,
                                         double theta_deg);

// Layout (sizes, scales) the phantom uses, with the defaults of `p` resolved.
[[nodiscard]] phantom::VolumeLayout macula_layout(const MaculaPhantomParams& p);
// The per-B-scan shifts the acquisition artefacts of `p` apply (zero when still).
[[nodiscard]] phantom::AcquisitionShifts macula_acquisition_shifts(const MaculaPhantomParams& p);
// True fovea centre in grid mm.
[[nodiscard]] Eigen::Vector2d macula_centre_mm(const MaculaPhantomParams& p);

struct DiskTruth {
    double diameter_mm = 0.0;  // mean 3-D distance of opposite points (Eq. 7.18, no square)
    double area_mm2 = 0.0;     // A_3D = A_2D / |cos(normal, z)| (Eq. 7.17)
    std::array<double, 3> eigenvalues_mm2{};  // major, minor, normal (Eq. 7.16)
    std::array<double, 2> semi_axes_mm{};     // sqrt(2 lambda) of major, minor
    std::array<double, 3> normal{};           // grid frame, z >= 0
};

struct HalfLineTruth {
    double angle_deg = 0.0;  // anatomical
    double rim_radius_mm = 0.0;
    double rim_height_mm = 0.0;
    double max_slope_deg = 0.0;
    std::array<double, 2> slope_point{};  // (r, h) mm
    double pit_flat_radius_mm = 0.0;
    std::optional<double> alpha_mm;  // Bezier family only
    std::optional<double> beta_mm;
    // Bezier family: control points (r, h) of the interior, of the exterior cubic and of its
    // sub-arc on [rim, R] (what a fit with P3 = the sample at R recovers).
    std::vector<std::array<double, 2>> interior_control_points;
    std::vector<std::array<double, 2>> exterior_control_points;
    std::vector<std::array<double, 2>> exterior_to_r_control_points;
    double rim_volume_mm3 = 0.0;        // this half-line's integral (before the 2 pi / n)
    double inner_rim_volume_mm3 = 0.0;
};

// How a value was obtained and a bound on (or measurement of) its numerical error.
struct TruthAccuracy {
    std::string method;
    double abs_error = 0.0;  // in the value's unit
};

struct MaculaTruth {
    bool line_scan = false;  // true: 2-D parameters only
    double centre_x_mm = 0.0;
    double centre_y_mm = 0.0;
    double cft_mm = 0.0;
    double rim_height_mm = 0.0;
    double pit_depth_mm = 0.0;
    double max_pit_slope_deg = 0.0;
    double pit_flat_diameter_mm = 0.0;
    DiskTruth rim;    // rim_diameter_mm, rim_disk_*
    DiskTruth slope;  // slope_diameter_mm, slope_disk_*
    DiskTruth pit_flat;
    double rim_volume_mm3 = 0.0;
    double inner_rim_volume_mm3 = 0.0;
    double pit_volume_mm3 = 0.0;
    std::optional<double> alpha_mean_mm;
    std::optional<double> beta_mean_mm;
    std::vector<HalfLineTruth> half_lines;
    std::vector<std::pair<std::string, TruthAccuracy>> accuracy;  // per output name
};

// Truth for the phantom `p` under the analysis settings `o` (no scan is generated).
[[nodiscard]] MaculaTruth macula_truth(const MaculaPhantomParams& p,
                                       const MaculaTruthOptions& o = {});

// Grid mm of every A-scan of the phantom `p`, B-scan after B-scan (index b * size_x + a): the
// points where the volume, line and radial phantoms sample the same continuous eye.
[[nodiscard]] std::vector<Eigen::Vector2d> macula_sample_points(const MaculaPhantomParams& p);
// Grid direction of radial line k (unit, Start -> End), radial phantoms only.
[[nodiscard]] Eigen::Vector2d radial_line_direction(const MaculaPhantomParams& p, int k);

struct MaculaPhantom {
    io::Scan scan;
    MaculaTruth truth;
    Eigen::Vector2d centre_mm = Eigen::Vector2d::Zero();  // true fovea centre, grid mm
    phantom::GridFrame frame;
};

// Generates the scan (segmentation, pixels, SLO, ETDRS grid) and its truth.
[[nodiscard]] MaculaPhantom make_macula_phantom(const MaculaPhantomParams& p,
                                                const MaculaTruthOptions& o = {});

// The FILE.truth.json document: generator options, octshape version, parameters, per-half-line
// values and per-value method and accuracy.
[[nodiscard]] nlohmann::ordered_json macula_truth_json(const MaculaTruth& t,
                                               const MaculaPhantomParams& p,
                                               const MaculaTruthOptions& o);

}  // namespace octshape::retina
