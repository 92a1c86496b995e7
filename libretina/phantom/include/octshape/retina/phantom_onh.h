#pragma once
// Optic-nerve-head phantom: a synthetic Spectralis-style ONH volume whose true ONH parameters
// parameters are known independently of the analysis code (docs/phantoms.md, "ONH phantoms").
//
// Geometry (all mm, grid frame: x = A-scan index * ScaleX, y = B-scan index * Distance,
// height z = -depth):
//  * BM/RPE: a quadratic height z_bm(x, y) = z_c + |d|^2 / (2 R) + t . d, d = (x, y) - c
//    (eye-wall curvature radius R, tilt t). The device BM line is missing inside the BMO.
//  * BMO: the ellipse c + Rot(theta) diag(a, b) (cos p, sin p). Normalised coordinates
//    v = diag(1/a, 1/b) Rot(-theta) ((x, y) - c) turn it into the unit circle; rho = |v|,
//    phi = atan2(v).
//  * ILM: the surface X(s, phi) = (c + Rot diag(a, b) rho(s) (cos phi, sin phi),
//    z_bm(x, y) + w(s)): a meridian curve (rho(s), w(s)) swept around the BMO centre in the
//    normalised frame and sheared vertically onto the BM, so that the height above the RPE is
//    h = w(s). w is the generating graph f(s); rho(s) = s + B bump(f(s)) pushes the cup wall
//    outward in a band of heights, which undercuts the rim (an overhang no height field can
//    describe). Signed projected area element: dA = a b rho rho'(s) ds dphi (Eq. 8.8-8.9).

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include "octshape/io/scan.h"
#include "octshape/retina/phantom_common.h"

namespace octshape::retina {

enum class OnhShape { kCupped, kSwollen, kOverhang };
enum class CupProfile {
    kBowl,       // -D (1 - (s/rho_c)^k)^3 for s < rho_c: smooth (C2) at the cup edge
    kSpherical,  // a spherical cap of depth D through the cup edge (for closed-form tests)
};

[[nodiscard]] std::string to_string(OnhShape shape);
[[nodiscard]] std::string to_string(CupProfile profile);

// The meridian profile of the ILM: height above the BM f(s) (mm) as a function of the
// normalised radius s (1 = the BMO), and the undercut. Defaults: the cupped preset.
struct OnhProfileParams {
    double retina_thickness_mm = 0.30;  // T: f far from the disc
    double rim_height_mm = 0.15;        // H: rim term H u e^(1-u), u = s^2 / rho_r^2
    double rim_radius = 1.2;            // rho_r: where the rim term peaks (BMO radii)
    double swelling_mm = 0.0;           // P: swelling term P exp(-s^2 / (2 sigma^2))
    double swelling_width = 0.9;        // sigma (BMO radii)
    double cup_depth_mm = 0.60;         // D: depth of the cup term at the centre
    double cup_radius = 0.95;           // rho_c: cup term is zero for s >= rho_c (BMO radii)
    int cup_exponent = 4;               // k (even >= 2): larger = flatter floor, steeper wall
    CupProfile cup_profile = CupProfile::kBowl;
    double undercut = 0.0;                // B: outward push of the wall (BMO radii); 0 = none
    double undercut_height_mm = 0.05;     // centre of the pushed height band (above the BM)
    double undercut_halfwidth_mm = 0.20;  // half-width of that band

    // Throws UsageError naming the bad field.
    void validate() const;
};

// All options of `octshape phantom onh`. Defaults: a full-size right-eye cupped disc.
struct OnhPhantomParams {
    OnhShape shape = OnhShape::kCupped;
    io::Laterality eye = io::Laterality::kOD;
    std::uint64_t seed = 1;
    int num_bscans = 145;                    // B-scans (first one most inferior)
    int num_ascans = 384;                    // A-scans per B-scan
    int depth_px = 496;                      // pixels per A-scan
    double field_mm = 4.35;                  // scanned square: ScaleX = field / A-scans,
                                             // Distance = field / (B-scans - 1)
    double scale_z_mm = 0.0038717;           // ScaleZ of every real Spectralis file
    double bm_centre_depth_fraction = 0.62;  // depth of the BM at the BMO centre / image depth
    // BMO ellipse (grid frame).
    double bmo_offset_x_mm = 0.06;  // BMO centre minus the field centre
    double bmo_offset_y_mm = -0.04;
    double bmo_semi_major_mm = 0.92;  // a (BMO area pi a b = 2.20 mm^2 by default)
    double bmo_semi_minor_mm = 0.76;  // b <= a
    double bmo_rotation_deg = 80.0;   // angle of the major axis from grid +x towards +y
    // BM/RPE quadratic.
    double eye_radius_mm = 12.0;  // curvature radius of the eye wall; 0 = flat
    double tilt_x = 0.03;         // dz/dx of the BM at the BMO centre
    double tilt_y = -0.02;        // dz/dy
    OnhProfileParams profile;     // ILM meridian profile (see onh_profile_preset)
    // Pixels.
    int speckle_looks = 4;  // multiplicative speckle ~ Gamma(L, 1/L) (mean 1)
    // Speckle grain (phantom::SpeckleParams): autocorrelation half-widths in pixels along the
    // A-scan and across A-scans; 0 0 = independent pixels (docs/phantoms.md, "Speckle").
    double speckle_axial_half_width_px = 0.0;
    double speckle_lateral_half_width_px = 0.0;
    // Radial scan (ScanPattern 5) of the SAME eye: radial_lines B-scans of line_length_mm and
    // num_ascans A-scans each, line k at k * 180 / radial_lines deg from grid +x towards +y
    // (superior), all through the crossing = BMO centre + (crossing_offset_um,
    // crossing_offset_y_um) um in the grid frame. The eye and the truth's grid frame are those of the volume these parameters
    // make (num_bscans, field_mm), so a volume and a radial phantom of the same parameters
    // sample one continuous eye (onh_sample_points).
    bool radial = false;
    int radial_lines = 24;
    double line_length_mm = 4.35;
    double crossing_offset_um = 0.0;    // along grid +x
    double crossing_offset_y_um = 0.0;  // along grid +y (re-scan benches: any direction)
    // What the acquisition adds (axial motion, jitter, vessel shadows, a cleft, device-line
    // faults; docs/phantoms.md): the pixels and device lines change, the truth does not.
    phantom::AcquisitionArtefacts artefacts;

    // Throws UsageError naming the bad field (geometry that does not fit the image is
    // reported by make_onh_phantom, which knows every column).
    void validate() const;
};

// The ILM profile of a shape: cupped (bowl cup below the RPE, rim), swollen (dome above the
// RPE with a shallow central dip, no cup), overhang (deep steep-walled cup whose wall is pushed
// outward under the rim: some vertical lines meet the ILM three times).
[[nodiscard]] OnhProfileParams onh_profile_preset(OnhShape shape);
// Default parameters with the profile of `shape`.
[[nodiscard]] OnhPhantomParams onh_phantom_preset(OnhShape shape);

// Grid position (mm, the truth's grid frame) of every A-scan, B-scan-major: the volume's grid
// nodes, or the radial lines' A-scans. The one place the volume and radial phantoms differ in
// where they sample the eye.
[[nodiscard]] std::vector<Eigen::Vector2d> onh_sample_points(const OnhPhantomParams& params);
// Radial phantoms: the lines' crossing (grid mm) and the unit grid direction Start -> End of
// line k.
[[nodiscard]] Eigen::Vector2d onh_radial_crossing(const OnhPhantomParams& params);
[[nodiscard]] Eigen::Vector2d onh_radial_direction(const OnhPhantomParams& params, int k);

// The generating geometry, evaluated exactly (no sampling). Everything the truth, the pixels
// and the device lines use comes from here.
class OnhPhantomGeometry {
  public:
    explicit OnhPhantomGeometry(const OnhPhantomParams& params);

    // Grid and scales.
    [[nodiscard]] double scale_x_mm() const { return scale_x_mm_; }
    [[nodiscard]] double distance_mm() const { return distance_mm_; }
    [[nodiscard]] double scale_z_mm() const { return scale_z_mm_; }
    [[nodiscard]] const Eigen::Vector2d& bmo_centre() const { return centre_; }
    // Columns of Rot(theta) diag(a, b): the normalised frame -> grid mm offsets.
    [[nodiscard]] const Eigen::Matrix2d& frame() const { return frame_; }

    // BM/RPE height (mm) and its gradient.
    [[nodiscard]] double bm_height(double x, double y) const;
    [[nodiscard]] Eigen::Vector2d bm_gradient(double x, double y) const;
    // Normalised coordinates of a grid point (the BMO is |v| = 1).
    [[nodiscard]] Eigen::Vector2d normalised(double x, double y) const;

    // Meridian curve: height above BM w(s), normalised radius rho(s), and derivatives.
    [[nodiscard]] double w(double s) const;
    [[nodiscard]] double dw(double s) const;
    [[nodiscard]] double rho(double s) const;
    [[nodiscard]] double drho(double s) const;
    // Largest s the curve is tabulated for (covers every grid column).
    [[nodiscard]] double s_max() const { return s_max_; }
    // All s with rho(s) = target, ascending: in [0, s_max], and beyond it up to the columns a
    // volume's lateral jitter samples (the truth never asks there).
    [[nodiscard]] std::vector<double> rho_roots(double target) const;
    // Heights above the BM (mm) where the vertical line at normalised radius `r` meets the
    // ILM, descending (the first is what a device reports as the ILM).
    [[nodiscard]] std::vector<double> crossings(double r) const;
    // s where the profile is not C-infinity (cup edge, undercut band edges).
    [[nodiscard]] std::vector<double> kinks() const;

    // ILM surface point and partial derivatives at (s, phi).
    [[nodiscard]] Eigen::Vector3d surface(double s, double phi) const;
    [[nodiscard]] Eigen::Vector3d surface_ds(double s, double phi) const;
    [[nodiscard]] Eigen::Vector3d surface_dphi(double s, double phi) const;

    // True when (x, y, z) is tissue (below the ILM), false in the vitreous.
    [[nodiscard]] bool in_tissue(double x, double y, double z) const;
    // Heights (mm, absolute z) where the vertical line at (x, y) meets the ILM, descending.
    [[nodiscard]] std::vector<double> ilm_heights(double x, double y) const;

  private:
    OnhProfileParams profile_;
    double scale_x_mm_ = 0.0;
    double distance_mm_ = 0.0;
    double scale_z_mm_ = 0.0;
    double semi_major_mm_ = 0.0;
    double curvature_ = 0.0;  // 1 / R (0 = flat)
    Eigen::Vector2d tilt_ = Eigen::Vector2d::Zero();
    double z_centre_ = 0.0;
    Eigen::Vector2d centre_ = Eigen::Vector2d::Zero();
    Eigen::Matrix2d frame_ = Eigen::Matrix2d::Identity();
    Eigen::Matrix2d frame_inv_ = Eigen::Matrix2d::Identity();
    double sphere_radius_mm_ = 0.0;  // spherical cup only
    double s_max_ = 0.0;
    double reach_ = 0.0;  // >= s_max_: the farthest jittered column (rho_roots)
    std::vector<double> pieces_;  // s-boundaries of the intervals where rho is monotone
};

// How finely the truth is computed; every value is computed twice, the second time with all
// steps halved, and the change is reported as its accuracy.
struct OnhTruthOptions {
    double s_step = 0.01;            // sub-interval of the 8-point Gauss-Legendre rule in s
    int phi_steps = 720;             // trapezoid nodes in phi (periodic: spectral accuracy)
    int mrw_points = 360;            // BMO points, uniform in the ellipse parameter angle
    double mrw_search_step = 0.008;  // coarse closest-point grid (BMO radii and radians)

    void validate() const;
};

// One truth value and how it was obtained.
struct TruthAccuracy {
    std::string name;
    std::string method;
    double value = 0.0;         // with halved steps (the reported value)
    double value_coarse = 0.0;  // with the options' steps
    double abs_change = 0.0;    // |value - value_coarse|: bounds the quadrature error
};

// BMO-MRW in the B-scan planes of a radial phantom (the device's definition): where line k
// crosses the true BMO ellipse (two points per line, z = BM height) and the closest point of
// the true ILM curve in line k's vertical plane, found by a dense search along the meridian
// parameter s of both branches of the curve (the line meets the circle rho(s) of the
// normalised frame twice) and refined by golden section. Index 2 k + side (side 0 towards the
// line's Start, 1 towards its End).
struct OnhInplaneTruth {
    std::vector<Eigen::Vector3d> bmo_points_mm;
    std::vector<Eigen::Vector3d> mrw_points_mm;
    std::vector<double> mrw_mm;
    std::vector<double> anatomical_deg;  // of the BMO point about the BMO centre
    std::vector<int> line;
    double mean_mm = 0.0;
    double min_mm = 0.0;
    double max_mm = 0.0;
    std::array<double, 12> sector_mm{};  // the clock-hour convention of OnhTruth
    std::array<int, 12> sector_points{};
    double abs_change_mm = 0.0;  // largest per-point change with the search step doubled
};

struct OnhTruth {
    bool has_cup = false;
    double cup_volume_mm3 = 0.0;      // positive
    double conht_mm = 0.0;            // top ILM crossing minus RPE at the BMO centre
    double bmo_volume_mm3 = 0.0;      // inside the BMO, h >= 0
    double total_volume_mm3 = 0.0;    // 1.5 mm disc around the BMO centre, h >= 0
    double annular_volume_mm3 = 0.0;  // 1.5 mm disc outside the BMO, h >= 0
    double bmo_area_mm2 = 0.0;        // pi a b
    std::array<double, 2> bmo_semi_axes_mm{};
    double bmo_orientation_deg = 0.0;             // major axis from grid +x, [0, 180)
    double bmo_orientation_anatomical_deg = 0.0;  // major axis from nasal towards superior
    std::array<double, 2> bmo_centre_mm{};        // grid frame
    double rpe_centre_height_mm = 0.0;            // z of the RPE at the BMO centre
    double mrw_mean_mm = 0.0;            // mean over the BMO points (uniform parameter angle)
    double mrw_mean_arclength_mm = 0.0;  // the same weighted by ellipse arclength
    double mrw_min_mm = 0.0;
    double mrw_max_mm = 0.0;
    // 12 clock-hour sectors centred on anatomical 0, 30, ..., 330 deg (0 = nasal,
    // 90 = superior); sector k holds the BMO points with angle in [30k - 15, 30k + 15).
    std::array<double, 12> mrw_sector_mm{};
    std::array<int, 12> mrw_sector_points{};
    double mrw_area_mm2 = 0.0;    // Eq. 8.23
    double bending_energy = 0.0;  // lambda2 + lambda3 of the BMO-region normal tensor
    std::vector<Eigen::Vector3d> bmo_points_mm;  // the ellipse points (z = BM height)
    std::vector<Eigen::Vector3d> mrw_points_mm;  // their closest points on the ILM
    std::vector<double> mrw_mm;                  // per point
    std::vector<double> bmo_anatomical_deg;      // per point
    std::vector<TruthAccuracy> accuracy;
    bool has_inplane = false;  // radial phantoms
    OnhInplaneTruth inplane;
    double seconds = 0.0;  // time taken
};

// Computes the truth from the generating functions (never from sampled pixels or lines).
[[nodiscard]] OnhTruth compute_onh_truth(const OnhPhantomParams& params,
                                         const OnhTruthOptions& options = {});

struct OnhPhantom {
    io::Scan scan;
    OnhTruth truth;
};

// Renders the scan (metadata, SLO, device ILM/BM lines, speckled pixels) and computes the
// truth. Throws UsageError when the geometry does not fit the image.
[[nodiscard]] OnhPhantom make_onh_phantom(const OnhPhantomParams& params,
                                          const OnhTruthOptions& truth_options = {});
// The per-B-scan shifts the acquisition artefacts of `params` apply (zero when still).
[[nodiscard]] phantom::AcquisitionShifts onh_acquisition_shifts(const OnhPhantomParams& params);
// Only the scan (no truth).
[[nodiscard]] io::Scan render_onh_scan(const OnhPhantomParams& params);

// The truth file: parameters, options, the method and accuracy of every value, version.
[[nodiscard]] nlohmann::json onh_truth_to_json(const OnhPhantomParams& params,
                                               const OnhTruthOptions& options,
                                               const OnhTruth& truth);

}  // namespace octshape::retina
