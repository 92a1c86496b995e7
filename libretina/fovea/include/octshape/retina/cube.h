#pragma once
// CuBe: the cubic-Bezier model of the fovea (thesis §7.1-7.3, docs/algorithms/cube.md).
//
// Pipeline: thickness map ILM - BM (Eq. 7.13 step 1) -> centre (minimum near the device centre,
// Eq. 7.13) -> n radial half-lines by bilinear interpolation (§7.2.1 step 2) -> split at the rim
// (the maximum) -> least-squares cubic Beziers, interior (Eq. 7.5, 7.7-7.10) and exterior
// (Eq. 7.6, 7.11-7.12) -> the §7.3 parameters.
//
// Frames: grid mm (x along a B-scan, y across B-scans) for positions and disk points; half-line
// angles are anatomical (0 deg nasal, 90 deg superior, both eyes) through ScanGeometry.
// Missing values are NaN in every double of the results below (kMissing); writers turn them
// into JSON null / CSV "NA". Nothing here logs or exits.

#include <Eigen/Core>
#include <array>
#include <limits>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "octshape/io/scan.h"
#include "octshape/retina/lateral_registration.h"

namespace octshape::retina {

inline constexpr double kMissing = std::numeric_limits<double>::quiet_NaN();

// Retinal thickness M(x, y) = ILM height - BM height in mm on the scan grid (row b = B-scan,
// column a = A-scan); NaN where either boundary is missing.
struct ThicknessMap {
    int rows = 0;            // B-scans
    int cols = 0;            // A-scans
    double dx_mm = 0.0;      // ScaleX
    double dy_mm = 0.0;      // Distance (0 for a line scan)
    std::vector<double> mm;  // rows * cols, row-major
    int num_missing = 0;     // nodes without a thickness, for any reason (the counts below too)
    // Nodes whose ILM or BM lies outside the image (above row 0 or below its last row), and
    // whose ILM lies below the BM: impossible segmentations, kept as missing values.
    int num_outside_image = 0;
    int num_inverted = 0;

    [[nodiscard]] double at(int b, int a) const {
        return mm[static_cast<std::size_t>(b) * static_cast<std::size_t>(cols) +
                  static_cast<std::size_t>(a)];
    }
    // Bilinear interpolation at grid mm (x, y): NaN outside the grid or when one of
    // the four surrounding nodes is missing. One row: linear along x (y must be 0).
    [[nodiscard]] double sample(double x_mm, double y_mm) const;
};

// A node whose ILM or BM lies outside the image's depth (SizeZ pixels), or whose ILM lies below
// its BM, is missing (and counted). Throws AnalysisError when the scan has no ILM/BM lines or no
// valid thickness at all.
[[nodiscard]] ThicknessMap thickness_map(const io::Scan& scan);

// Noise SD of the map's nodes (mm), from the second differences along the A-scans (x): for
// white noise of SD s, M[a-1] - 2 M[a] + M[a+1] has SD s sqrt(6); the retina's own curvature adds
// |M''| dx^2 (< 0.1 um at 11.7 um spacing). Robust: 1.4826 x the median absolute second
// difference / sqrt(6). 0 when fewer than 16 valid triples.
[[nodiscard]] double thickness_noise_sd(const ThicknessMap& m);

// Where the interior and exterior segments of a half-line meet (docs/algorithms/cube.md "Rim
// point"). kMaximum: at the maximum sample (the thesis's split), only the rim height
// fitted. kCrest: the rim is still the profile's maximum, but among the samples that could be
// it: the rim radius is an unknown of the joint fit, bounded to the crest, i.e. the span of the
// samples within 3 noise SDs (thickness_noise_sd) of the maximum sample, widened by half a
// sample step. Under segmentation noise the maximum sample wanders over the flat crest and is
// biased outward (rim diameter 3-6 %, rim volume 8-15 % at 1 axial pixel); without noise the
// crest is the maximum sample's neighbourhood, so a profile that is not a CuBe curve keeps its
// rim at its maximum.
enum class RimPoint { kCrest, kMaximum };
[[nodiscard]] std::string_view to_string(RimPoint r);
// "crest" | "maximum"; throws UsageError otherwise.
[[nodiscard]] RimPoint parse_rim_point(std::string_view s);

struct CubeParams {
    int num_half_lines = 24;           // n, even (opposite half-lines pair up, Eq. 7.18); 15 deg
    double radius_mm = 2.0;            // R, length of each half-line (§7.2.1: 2 mm)
    double sample_spacing_mm = 0.0;    // radial sample spacing; 0 = the scan's ScaleX
    double tau_mm = 0.005;             // pit-flat threshold above CFT (Eq. 7.24; 5 um)
    double inner_radius_mm = 0.5;      // r_u of the inner rim volume (Eq. 7.28; ETDRS centre)
    double search_radius_mm = 1.0;     // centre search around the device centre (§7.2.1, 1 mm)
    double tie_tolerance_mm = 0.0005;  // minima within 0.5 um are ties -> median
    // Gaussian SD of the smoothing applied to the thickness map for locating the centre only
    // (docs/algorithms/cube.md "Centre"): the minimum of noisy nodes wanders over a flat pit
    // floor and is biased low. 0 = the raw minimum.
    double centre_smoothing_mm = 0.05;
    // Half-width of the window around the minimum node in which a quadratic surface is fitted
    // to M; its vertex, when it lies in the window, is the centre (between nodes: B-scans are
    // 39-125 um apart). 0 = the node.
    double centre_fit_radius_mm = 0.06;
    int max_rounds = 100;              // alternating LS / foot-point rounds
    double energy_tolerance = 1e-10;   // stop on relative energy change below this
    double rmse_warning_um = 10.0;     // QC "fit RMSE high" above this (thesis: 1.0-7.1 um)
    RimPoint rim_point = RimPoint::kCrest;
    // Samples under segmentation noise (docs/algorithms/cube.md "Radial samples under noise"):
    // when the map's node noise SD (thickness_noise_sd) is at least this, a volume's CFT pass
    // fits local regressions (quadratic in the radius, linear across, over every valid node of
    // the half-line's angular sector within a radial window) and its final fit fits sector bins
    // (the sector's nodes in runs of equal count, each at its RMS radius), instead of the
    // bilinear mixes of 4 nodes; the reported RMSE stays that of the bilinear samples. Below it
    // (noise-free maps, the device's smooth lines) and for line scans the samples are the
    // bilinear ones. +inf = always bilinear.
    double local_fit_min_noise_um = 0.5;
    // Lateral registration of a volume's B-scans before the thickness map (the caller applies it:
    // app/commands/macula_eye.cpp; docs/algorithms/cube.md, step 1). The macula's lines are
    // smoothed along the A-scans (Gaussian SD 4 A-scans) for the estimate: its surfaces are
    // flat over most of the field, where single values' noise otherwise makes the fit's slopes
    // and favours fractional shifts (measured: bench macula_motion).
    // The cut-off is at most 8 B-scans (0.38 mm on a 128-B-scan 6 mm cube; 0.75 mm from 94 um
    // apart on): on dense cubes it halves the false shifts of a noisy still eye.
    // The lines are moved by whole A-scans: a fractional shift blends two device values, which
    // changes the map's noise estimate (and with it the rim crest's tolerance) in the moved
    // B-scans; on the real Topcon cube 2.1 -> 0.7 um.
    // The passes stop at a step of 0.01 A-scans (the ONH's 1e-4): the lines move by whole
    // A-scans, and on the real cubes the shifts then differ by <= 0.15 um from 20 passes' for a
    // third fewer passes (one Topcon B-scan at -1.50 A-scans now rounds to 1, not 2;
    // docs/algorithms/cube.md, "Cost").
    LateralRegistrationParams lateral_registration{.smooth_wavelength_bscans = 8.0,
                                                   .line_smoothing_ascans = 4.0,
                                                   .whole_ascans = true,
                                                   .step_tolerance_ascans = 0.01};
    // Forces the centre (grid mm) instead of searching: validation from a known centre. Under
    // noise the pit floor and the CFT pass's centre sample are built about it as about a
    // searched centre, so that only the centre changes (docs/algorithms/cube.md "Centre").
    std::optional<Eigen::Vector2d> centre_mm;
    // Throws UsageError naming the bad field.
    void validate() const;
};

// One fitted cubic Bezier and how the fit went.
struct BezierFit {
    std::array<Eigen::Vector2d, 4> control{};  // (r, thickness) mm
    std::vector<double> t;                     // foot-point parameter of each sample
    double sse_mm2 = 0.0;                      // sum of squared distances to the curve
    int num_samples = 0;
    int rounds = 0;
    bool converged = false;  // stopped on the energy criterion (not on max_rounds)
};

struct FitSettings {
    int max_rounds = 100;
    double energy_tolerance = 1e-10;
    // P0.y (the centre height) is a fitted unknown instead of the first sample's height (the
    // first sample stays at t = 0); used to estimate CFT from the model.
    bool free_start_height = false;
    // fit_rim_profile only: kCrest bounds the rim radius to the samples within
    // crest_tolerance_mm of the maximum sample (analyse_macula: 3 x thickness_noise_sd).
    RimPoint rim_point = RimPoint::kCrest;
    double crest_tolerance_mm = 0.0;
    // fit_rim_profile only: also compute RimProfileFit::interior_cov (the final fit on sector
    // bins, for the max slope's noise term; otherwise left NaN).
    bool covariance = false;
};

// Interior fit (Eq. 7.5, 7.7-7.10): P0 = first sample, P3 = last sample, P1 = P0 + alpha (1,0),
// P2 = P3 - beta (1,0), 0 <= alpha, beta and alpha + beta <= P3.x - P0.x. Samples ordered by r.
[[nodiscard]] BezierFit fit_interior(std::span<const Eigen::Vector2d> samples,
                                     const FitSettings& s = {});
// Exterior fit (Eq. 7.6, 7.11-7.12): P0 = first sample (the rim), P1 = P0 + alpha (1,0), P2 free,
// P3 = last sample; kept a graph (P0.x <= P1.x <= P2.x <= P3.x).
[[nodiscard]] BezierFit fit_exterior(std::span<const Eigen::Vector2d> samples,
                                     const FitSettings& s = {});

// A whole half-line profile: interior and exterior sharing the rim point.
struct RimProfileFit {
    BezierFit interior;  // samples [0, rim index] (the centre first at t = 0, the rim sample free)
    BezierFit exterior;  // samples after the rim sample (the last one is P3, t = 1)
    Eigen::Vector2d rim{0.0, 0.0};  // (r_rim, h_rim) = interior P3 = exterior P0, mm
    int rounds = 0;                 // joint rounds run after the two start fits
    bool converged = false;
    // Covariance of the interior's (alpha, beta, r_rim, h_rim) under white noise on the samples,
    // linearised at the fit: s^2 (Z^T H Z)^-1 with H the Gauss-Newton matrix of Eq. 7.8, Z the
    // directions the active bounds and pinned unknowns leave free, s^2 the fit's residual
    // variance (docs/algorithms/cube.md "Max slope: the plug-in maximum's noise term"), mm^2.
    Eigen::Matrix4d interior_cov =
        Eigen::Matrix4d::Constant(std::numeric_limits<double>::quiet_NaN());
};

// Fits a half-line profile (samples ordered by r; the first is the centre (0, CFT), the last
// the exterior's end point) split at the rim sample `rim_index` (the maximum) with
// the rim *height* a model estimate (docs/algorithms/cube.md "Rim point"): r_rim is the rim
// sample's radius; h_rim, the interior's (alpha, beta) and the exterior's (alpha, P2) minimise
// the joint Eq. 7.8 energy of both segments (started from fit_interior / fit_exterior through
// the rim sample; alternating a linear least-squares step under the graph constraints with
// the foot points). Throws AnalysisError when a segment has too few samples.
// `start`, when given, is a fit of the same samples (e.g. the CFT pass, with P0.y free) that the
// rounds continue from instead of the two start fits; its P0.y is replaced by the first sample's.
[[nodiscard]] RimProfileFit fit_rim_profile(std::span<const Eigen::Vector2d> samples,
                                            int rim_index,
                                            const FitSettings& s = {},
                                            const RimProfileFit* start = nullptr);

[[nodiscard]] Eigen::Vector2d bezier_point(const std::array<Eigen::Vector2d, 4>& p, double t);
[[nodiscard]] Eigen::Vector2d bezier_derivative(const std::array<Eigen::Vector2d, 4>& p, double t);
// The t in [0, 1] with bezier_point(p, t).x() = x on a curve whose x is monotone (bisection to
// the last bit).
[[nodiscard]] double bezier_t_at_x(const std::array<Eigen::Vector2d, 4>& p, double x);

// Maximum slope of an interior CuBe curve (replacing the misprinted Eq. 7.20):
// s = dy / (sqrt(alpha beta) + w - alpha - beta) at t_m = sqrt(alpha) / (sqrt(alpha) +
// sqrt(beta)); w = P3.x - P0.x, dy = P3.y - P0.y. Infinite slope -> +inf.
struct MaxSlope {
    double slope = 0.0;  // dy/dx
    double t = 0.5;
};
[[nodiscard]] MaxSlope interior_max_slope(const std::array<Eigen::Vector2d, 4>& interior);

// Integral of y x dx/dt over [0, t1] (Eq. 7.27-7.28), exact (degree-8 polynomial).
[[nodiscard]] double bezier_volume_integral(const std::array<Eigen::Vector2d, 4>& p, double t1);

struct CubeHalfLine {
    double angle_deg = 0.0;                               // anatomical
    Eigen::Vector2d direction = Eigen::Vector2d::Zero();  // unit, grid frame
    // Where r = 0 lies (grid mm); NaN = the centre (every analysis: a radial scan's r are the
    // samples' distances from the centre, see foot_mm).
    Eigen::Vector2d origin_mm{kMissing, kMissing};
    // Radial scans: the foot of the centre on the half-line's B-scan (its point nearest the
    // centre, grid mm). The half-line's A-scans lie at foot + s * direction, s >= 0, and r =
    // sqrt(s^2 + |foot - centre|^2); their points are placed at centre + r * direction. NaN
    // for volumes and line scans.
    Eigen::Vector2d foot_mm{kMissing, kMissing};
    bool valid = false;  // the fit was possible (else `problem` says why)
    std::string problem;
    std::vector<double> r_mm;  // samples along the half-line
    std::vector<double> h_mm;  // thickness, NaN = missing
    int num_missing = 0;
    int num_missing_interior = 0;
    double rim_radius_mm = kMissing;
    double rim_height_mm = kMissing;
    double alpha_mm = kMissing;
    double beta_mm = kMissing;
    double max_slope_deg = kMissing;
    double slope_t = kMissing;
    Eigen::Vector2d slope_point{kMissing, kMissing};  // (r, h)
    double pit_flat_radius_mm = kMissing;             // NaN when the pit is shallower than tau
    double rim_volume_mm3 = kMissing;                 // this line's integral (before 2 pi / n)
    double inner_rim_volume_mm3 = kMissing;
    double rmse_um = kMissing;
    // What rmse_um is the root of: the sum of squared orthogonal distances (mm^2) over the
    // samples it is measured on (the bilinear samples when the fit ran on sector bins) and their
    // count. The eye's RMSE sums these, so the two RMSEs agree on what a sample is.
    double rmse_sse_mm2 = 0.0;
    int rmse_num_samples = 0;
    BezierFit interior;
    BezierFit exterior;
    Eigen::Matrix4d interior_cov =  // RimProfileFit::interior_cov
        Eigen::Matrix4d::Constant(std::numeric_limits<double>::quiet_NaN());
};

struct CubeDisk {
    double diameter_mm = kMissing;  // mean 3-D distance of opposite points (Eq. 7.18/7.23)
    double area_mm2 = kMissing;     // A_3D = A_2D / |cos(normal, z)| (Eq. 7.17)
    std::array<double, 3> eigenvalues_mm2{kMissing, kMissing, kMissing};  // major, minor, normal
    std::array<double, 2> semi_axes_mm{kMissing, kMissing};               // sqrt(2 lambda)
    std::array<double, 3> normal{kMissing, kMissing, kMissing};           // grid frame, z >= 0
    std::vector<Eigen::Vector3d> points;  // grid mm, in angular order
};

// The fitted profile of a half-line at distance `r_mm` from its origin: the interior Bezier
// up to the rim, the exterior beyond (Eq. 7.5-7.6), each solved for r with bezier_t_at_x. NaN
// for an invalid half-line and outside [0, R] (r_mm.back()).
[[nodiscard]] double fitted_thickness_mm(const CubeHalfLine& h, double r_mm);

// The disk through points in angular order (rim, slope or pit-flat points, grid mm): covariance
// eigen-analysis, shoelace area over |cos(normal, z)| and the opposite-point diameter
// (Eq. 7.16-7.18). What analyse_macula reports; exposed for bench/macula_crb.
[[nodiscard]] CubeDisk cube_disk(std::vector<Eigen::Vector3d> points);

// A radial scan's analysis (docs/algorithms/cube.md "Radial scans"): the lines as read
// (retina/radial_geometry.h) and how far the centre found lies from their crossing.
struct CubeRadial {
    int num_lines = 0;
    double line_length_mm = kMissing;
    double angular_step_deg = kMissing;
    bool regular = true;        // angular steps within 2 % of 180 / lines
    double max_miss_mm = kMissing;  // how far the lines miss their common crossing
    // The centre (thickness minimum near the crossing) minus the crossing, radial mm, its
    // length, and the QC limit on it (flag "centre off the line crossing").
    Eigen::Vector2d centre_offset_mm{kMissing, kMissing};
    double centre_offset_distance_mm = kMissing;
    double centre_offset_limit_mm = kMissing;
    int num_bmo_fields = 0;  // HSF-OCT-104 B-scans with BMO fields (never used)
};

struct CubeResult {
    bool line_scan = false;     // 2-D parameters only
    // A radial scan (ScanPattern 5): positions are in the radial frame (mm from the lines'
    // crossing, x = SLO +x, y = superior), half-lines run along the B-scans.
    bool radial_scan = false;
    CubeRadial radial;
    std::string centre_source;  // "device thickness grid", "scan centre" or "given"
    Eigen::Vector2d search_centre_mm = Eigen::Vector2d::Zero();
    Eigen::Vector2d centre_mm = Eigen::Vector2d::Zero();  // grid mm
    int num_tied_minima = 0;
    double sample_spacing_mm = 0.0;
    double cft_mm = kMissing;                // Eq. 7.14, the model's shared P0.y
    double cft_sample_mm = kMissing;         // M at the centre (the raw sample)
    double rim_height_mm = kMissing;         // Eq. 7.15
    double pit_depth_mm = kMissing;          // Eq. 7.19
    double max_pit_slope_deg = kMissing;     // mean of atan(s_i) (Eq. 7.20-7.21); sector bins: less its noise term
    double pit_flat_diameter_mm = kMissing;  // Eq. 7.26
    CubeDisk rim;                            // rim_diameter_mm, rim_disk_* (Eq. 7.16-7.18)
    CubeDisk slope;                          // slope_diameter_mm, slope_disk_* (Eq. 7.22-7.23)
    CubeDisk pit_flat;                       // pit_flat_disk_* (Eq. 7.24-7.26)
    double rim_volume_mm3 = kMissing;        // Eq. 7.27
    double inner_rim_volume_mm3 = kMissing;  // Eq. 7.28
    double pit_volume_mm3 = kMissing;        // Eq. 7.29
    double alpha_mean_mm = kMissing;
    double beta_mean_mm = kMissing;
    double rmse_um = kMissing;  // over every sample of every valid half-line
    double thickness_noise_sd_um = kMissing;  // thickness_noise_sd of the map (sets the crest)
    // The noise-adaptive estimators (CubeParams::local_fit_min_noise_um): whether they were
    // used (the CFT pass on local-fit samples, the final fit on sector bins; else bilinear
    // samples), and the half-width of the window whose quadratic vertex placed the centre (NaN
    // when the centre is given or not refined).
    bool noise_adaptive_samples = false;
    double centre_fit_radius_mm = kMissing;
    std::vector<CubeHalfLine> half_lines;
    // What the lateral registration of the B-scans did (filled by the caller that registered the
    // scan; analyse_macula itself analyses the scan as given).
    LateralRegistration lateral_registration;
    std::vector<std::string> qc_flags;  // short, stable phrases
    std::vector<std::string> notes;
    ThicknessMap map;
};

// The whole analysis of one scan: a volume (ScanPattern 3/4 or unknown with > 1 parallel
// B-scan), a line through the fovea (ScanPattern 1) or a radial scan (ScanPattern 5, or
// unknown with B-scans that are not parallel; CubeParams::num_half_lines is then twice the
// number of lines and centre_mm is in the radial frame). Throws AnalysisError for other patterns or unusable
// segmentation, UsageError for bad params.
[[nodiscard]] CubeResult analyse_macula(const io::Scan& scan, const CubeParams& params = {});

}  // namespace octshape::retina
