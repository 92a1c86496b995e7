#pragma once
// The stages of the CuBe macula analysis (analyse_macula, cube.cpp) and what they hand each
// other; internal to octshape::fovea. The order, and what each stage decides:
//
//   check_macula_scan   volume or line scan through the fovea (else AnalysisError)
//   thickness_map       M = ILM - BM on the scan grid (public, cube.h)
//   find_centre         the fovea centre and the CFT sample (cube_sampling.cpp)
//   radial_samples      n half-lines of samples, local fits and sector nodes under noise
//   cft_pass            every half-line with its start height free: CFT = their mean (cube.cpp)
//   final_fit           every half-line with P0 = (0, CFT): curves and per-line parameters
//   summarise_macula    the eye's parameters, disks and volumes (cube_parameters.cpp)
//   macula_qc           QC flags that need the whole result
//
// Decisions and measurements behind each: docs/algorithms/cube.md.

#include <Eigen/Core>
#include <array>
#include <cmath>
#include <numbers>
#include <span>
#include <string>
#include <vector>

#include "octshape/io/scan.h"
#include "octshape/retina/cube.h"
#include "octshape/retina/radial_geometry.h"
#include "octshape/retina/scan_geometry.h"

namespace octshape::retina::cube_detail {

using V2 = Eigen::Vector2d;
using V3 = Eigen::Vector3d;
using Ctrl = std::array<V2, 4>;

inline constexpr double kPi = std::numbers::pi;
inline constexpr double kDeg = 180.0 / kPi;

// ---- shared helpers ------------------------------------------------------------------------

// x(t) = x on a curve whose x is monotone: bisection to the last bit (cube_fit.cpp).
[[nodiscard]] double solve_x(const Ctrl& c, double x);

// The median of v (an even count: the mean of the middle two) (cube_sampling.cpp).
[[nodiscard]] double median(std::vector<double> v);

// Covariance eigen-analysis, shoelace area and opposite-point diameter (Eq. 7.16-7.18)
// (cube_parameters.cpp).
[[nodiscard]] CubeDisk disk(std::vector<V3> pts);

// ---- stage 1: the scan ---------------------------------------------------------------------

// thickness_map between lines `upper` and `lower` (indices into the scan's lines; the names in
// messages are the scan's line names) (cube_sampling.cpp). thickness_map is (ILM, BM).
[[nodiscard]] ThicknessMap thickness_map_of_lines(const io::Scan& scan, int upper, int lower);

// True for a line scan (one B-scan through the fovea), false for a volume; AnalysisError for
// any other pattern, or a scan without the spacings the analysis needs.
[[nodiscard]] bool check_macula_scan(const io::Scan& scan);

// The field must hold the model: a scan narrower than the half-lines' length R (a volume: or
// shorter) cannot give a half-line with its rim inside; AnalysisError naming both sizes.
void check_macula_field(const ThicknessMap& m, const CubeParams& params, bool line_scan);

// ---- stage 2: the centre (docs/algorithms/cube.md step 2, Eq. 7.13) -------------------------

struct CentreInput {
    const io::Scan& scan;
    const ThicknessMap& map;
    const ScanGeometry& geo;
    const CubeParams& params;
    bool line_scan = false;
    bool noisy = false;        // the noise-adaptive estimators are used
    double noise_sd_mm = 0.0;  // thickness_noise_sd of the map
};

// Under noise, the least-squares quadratic surface of the pit floor around the centre, over the
// window |u| <= half_x_mm, |w| <= half_y_mm: T = k0 + k1 u + k2 w + k3 u^2 + k4 u w + k5 w^2 with
// (u, w) = p - origin. The radial samples inside it that no local fit gives take its height
// (docs/algorithms/cube.md "Radial samples under noise").
struct PitFloor {
    V2 origin = V2::Zero();
    Eigen::Matrix<double, 6, 1> k = Eigen::Matrix<double, 6, 1>::Zero();
    double half_x_mm = 0.0;  // 0: none
    double half_y_mm = 0.0;
    [[nodiscard]] bool holds(const V2& p) const {
        return half_x_mm > 0.0 && std::fabs(p.x() - origin.x()) <= half_x_mm &&
               std::fabs(p.y() - origin.y()) <= half_y_mm;
    }
    [[nodiscard]] double at(const V2& p) const {
        const V2 d = p - origin;
        return k(0) + k(1) * d.x() + k(2) * d.y() + k(3) * d.x() * d.x() + k(4) * d.x() * d.y() +
               k(5) * d.y() * d.y();
    }
};

struct Centre {
    V2 search_centre_mm = V2::Zero();
    std::string source;  // CubeResult::centre_source
    V2 centre_mm = V2::Zero();
    double cft_mm = kMissing;  // M at the centre (the raw CFT sample)
    int num_tied_minima = 0;
    double fit_radius_mm = kMissing;  // CubeResult::centre_fit_radius_mm
    // Under noise, the height at the centre of a quadratic surface over half the centre window
    // (without it, the centre window's vertex height): the first sample of the CFT pass (NaN:
    // use cft_mm).
    double sample_mm = kMissing;
    PitFloor floor;  // under noise, when the quadratic surface was used
    std::vector<std::string> notes;
    std::vector<std::string> qc_flags;
};

[[nodiscard]] Centre find_centre(const CentreInput& in);

// ---- stage 3: radial samples (docs/algorithms/cube.md step 3) --------------------------------

struct RadialSamples {
    double spacing_mm = 0.0;
    std::vector<double> radii;             // the regular radii of every half-line
    std::vector<CubeHalfLine> half_lines;  // angle, direction, r_mm / h_mm samples
    // Under noise only: the bilinear samples at the regular radii (the RMSE is measured against
    // them) and every valid node of each half-line's sector (the final fit's sector bins).
    std::vector<std::vector<double>> bilinear;
    std::vector<std::vector<V2>> sector_nodes;
    bool noise_adaptive = false;
    double noise_sd_mm = 0.0;  // the map's noise estimate (thickness_noise_sd): the runs' length
};

[[nodiscard]] RadialSamples radial_samples(const ThicknessMap& m,
                                           const ScanGeometry& geo,
                                           const CubeParams& params,
                                           const V2& centre_mm,
                                           double cft_mm,
                                           double scale_x_mm,
                                           bool line_scan,
                                           bool noisy,
                                           const PitFloor& floor = {});

// Replaces every half-line's samples (but the centre) by its sector bins
// (docs/algorithms/cube.md "Radial samples under noise") (cube_sampling.cpp).
void sector_bin_samples(std::vector<std::vector<V2>>& nodes,
                        std::vector<CubeHalfLine>& lines,
                        const std::vector<CubeHalfLine>* profiles = nullptr,
                        double noise_sd_mm = 0.0);

// ---- stages 4 and 5: the fits (cube_fit.cpp) ------------------------------------------------

// The bilinear samples of a half-line at the regular radii (docs/algorithms/cube.md step 3), kept
// beside the sector bins for the RMSE and the count of missing values in the pit.
struct BilinearSamples {
    const std::vector<double>& r_mm;
    const std::vector<double>& h_mm;
};

// Fits one half-line's interior and exterior (fit_rim_profile) to its samples, started from
// `start` when given. With fs.free_start_height (the CFT pass) only the curves are set;
// otherwise also the half-line's parameters (half_line_parameters) and its RMSE, measured
// against `bilinear` when given (the fit then ran on sector bins). A half-line that cannot be
// fitted keeps valid = false and says why in `problem`.
void fit_half_line(CubeHalfLine& h,
                   double cft,
                   const CubeParams& p,
                   const FitSettings& fs,
                   const CubeHalfLine* start = nullptr,
                   const BilinearSamples* bilinear = nullptr);

struct CftPass {
    double cft_mm = kMissing;             // the mean of the free start heights
    std::vector<CubeHalfLine> free_fits;  // each half-line fitted with its own P0.y
};

// Stage 4: CFT as a model estimate (docs/algorithms/cube.md "CFT") (cube.cpp).
[[nodiscard]] CftPass cft_pass(const std::vector<CubeHalfLine>& lines,
                               double centre_sample_mm,
                               double cft_sample_mm,
                               const CubeParams& params,
                               double crest_mm);

// The found centre into the result (source, position, CFT sample, ties, fit window, its notes
// and flags): the same for volumes, lines and radial scans (cube.cpp).
void take_centre(CubeResult& res, Centre&& centre);

// Stages 4 and 5 on any half-lines (a volume's interpolated ones or a radial scan's measured
// ones): the CFT pass from the centre's sample, then the final fit; res.cft_sample_mm keeps the
// raw sample, res.cft_mm becomes the model's CFT, res.half_lines the fitted lines (cube.cpp).
void fit_half_lines(CubeResult& res, RadialSamples& samples, double centre_sample_mm,
                    const CubeParams& params, double crest_mm);

// Stage 5: every half-line fitted with P0 = (0, CFT), started from the CFT pass (cube.cpp).
void final_fit(RadialSamples& s, const CftPass& cft, const CubeParams& params, double crest_mm);

// ---- stage 6: parameters (cube_parameters.cpp) ----------------------------------------------

// Per half-line, from its fitted curves (Eq. 7.21-7.28): rim, handles, maximum slope, pit
// flat, volumes.
void half_line_parameters(CubeHalfLine& h, const CubeParams& p);

// The eye's parameters from its half-lines (Eq. 7.14-7.29): means, RMSE, disks and volumes;
// QC flags and notes about failed half-lines. Needs res.half_lines, res.cft_mm, res.centre_mm
// and res.line_scan; AnalysisError when no half-line could be fitted.
void summarise_macula(CubeResult& res, const CubeParams& params);

// QC flags that look at the whole result and the scan (pit values missing, RMSE, spacing,
// orientation, laterality, impossible segmentation kept as missing values).
void macula_qc(CubeResult& res,
               const io::Scan& scan,
               const ScanGeometry& geo,
               const CubeParams& params);

// The last gate: a result that is not finite or not physically possible where it is reported
// (CFT or rim height outside (0, image depth], a negative pit depth or volume, a disk wider
// than the scan) is refused with AnalysisError naming the value; a success never carries one.
void check_macula_result(const CubeResult& res, const io::Scan& scan);

// ---- the radial path (cube_radial.cpp, docs/algorithms/cube.md "Radial scans") -------------
//
//   radial_check        scales, lines (radial_geometry), the lines long enough for R
//   thickness_map       M = ILM - BM per line (rows = lines), as for a volume
//   radial_centre       thickness minimum near the crossing, refined by a quadratic surface
//   radial_half_lines   two half-lines per B-scan along its own line, from the foot of the
//                       centre, on the measured A-scans (no interpolation of a map)
//   cft_pass, final_fit, summarise_macula   as for a volume
//   radial_qc           the macula QC plus the radial flags (crossing offset, steps, misses)

// Throws AnalysisError when the scan's lines or scales cannot be analysed.
[[nodiscard]] RadialGeometry radial_check(const io::Scan& scan, const CubeParams& params);

struct RadialCentreInput {
    const ThicknessMap& map;
    const RadialGeometry& geo;
    const CubeParams& params;
    int size_x = 0;
};

// The centre in the radial frame (Centre::centre_mm; search_centre_mm = the crossing, 0).
[[nodiscard]] Centre radial_centre(const RadialCentreInput& in);

// 2 x lines half-lines in angular order (opposite half-lines n/2 apart), samples r_mm from the
// foot of `centre_mm` on each line at the A-scans within R; h_mm[0] = cft_mm.
[[nodiscard]] RadialSamples radial_half_lines(const ThicknessMap& m,
                                              const RadialGeometry& geo,
                                              const CubeParams& params,
                                              const V2& centre_mm,
                                              double cft_mm,
                                              int size_x);

// The crossing offset beyond which the QC flag "centre off the line crossing" is raised (mm).
[[nodiscard]] double radial_offset_limit_mm();

void radial_qc(CubeResult& res, const io::Scan& scan, const RadialGeometry& geo,
               const CubeParams& params);

// The radial driver (analyse_macula hands a radial scan to it).
[[nodiscard]] CubeResult analyse_macula_radial(const io::Scan& scan, const CubeParams& params);

}  // namespace octshape::retina::cube_detail
