// CuBe fovea analysis, the parameters (thesis §7.3, docs/algorithms/cube.md "Parameters"): per
// half-line from its curves, then the eye's means, disks and volumes, and the QC flags. Decisions:
// docs/algorithms/cube.md.

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <string>
#include <utility>

#include "cube_stages.h"
#include "octshape/error.h"
#include "octshape/retina/cube.h"

namespace octshape::retina {
using namespace cube_detail;

namespace cube_detail {

CubeDisk disk(std::vector<V3> pts) {
    CubeDisk out;
    const auto n = pts.size();
    V3 c = V3::Zero();
    for (const auto& q : pts) c += q;
    c /= static_cast<double>(n);
    Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
    for (const auto& q : pts) cov += (q - c) * (q - c).transpose();
    cov /= static_cast<double>(n);  // Eq. 7.16
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(cov);
    const V3 ev = es.eigenvalues();  // ascending
    V3 normal = es.eigenvectors().col(0);
    if (normal.z() < 0.0) normal = -normal;
    out.eigenvalues_mm2 = {ev(2), ev(1), ev(0)};
    out.semi_axes_mm = {std::sqrt(2.0 * std::max(0.0, ev(2))),
                        std::sqrt(2.0 * std::max(0.0, ev(1)))};
    out.normal = {normal.x() + 0.0, normal.y() + 0.0, normal.z() + 0.0};
    double a2 = 0.0;
    for (std::size_t i = 0; i < n; ++i) {
        const V3& p = pts[i];
        const V3& q = pts[(i + 1) % n];
        a2 += p.x() * q.y() - q.x() * p.y();
    }
    out.area_mm2 = std::fabs(0.5 * a2) / std::fabs(normal.z());  // Eq. 7.17
    double sum = 0.0;
    for (std::size_t i = 0; i < n / 2; ++i) sum += (pts[i] - pts[i + n / 2]).norm();
    out.diameter_mm = sum / static_cast<double>(n / 2);  // Eq. 7.18 without the square
    out.points = std::move(pts);
    return out;
}

void half_line_parameters(CubeHalfLine& h, const CubeParams& p) {
    const Ctrl& qi = h.interior.control;
    const double dy = qi[3].y() - qi[0].y();
    h.rim_radius_mm = qi[3].x();
    h.rim_height_mm = qi[3].y();
    h.alpha_mm = qi[1].x() - qi[0].x();
    h.beta_mm = qi[3].x() - qi[2].x();
    const MaxSlope ms = interior_max_slope(qi);
    h.max_slope_deg = std::atan(ms.slope) * kDeg;  // Eq. 7.21 averages these
    h.slope_t = ms.t;
    h.slope_point = bezier_point(qi, ms.t);  // Eq. 7.22
    // Pit flat (Eq. 7.24-7.25, both on the interior curve): y(t) = CFT + dy (3t^2 - 2t^3).
    if (p.tau_mm < dy) {
        const double target = p.tau_mm / dy;
        double lo = 0.0;
        double hi = 1.0;
        for (int it = 0; it < 200; ++it) {
            const double mid = 0.5 * (lo + hi);
            if (mid == lo || mid == hi) break;
            if (mid * mid * (3.0 - 2.0 * mid) < target) {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        h.pit_flat_radius_mm = bezier_point(qi, 0.5 * (lo + hi)).x();
    }
    // Volumes (Eq. 7.27-7.28).
    h.rim_volume_mm3 = bezier_volume_integral(qi, 1.0);
    const double ru = p.inner_radius_mm;
    if (ru <= qi[3].x()) {
        h.inner_rim_volume_mm3 = bezier_volume_integral(qi, solve_x(qi, ru));
    } else {
        const Ctrl& qe = h.exterior.control;
        const double te = ru >= qe[3].x() ? 1.0 : solve_x(qe, ru);
        h.inner_rim_volume_mm3 = h.rim_volume_mm3 + bezier_volume_integral(qe, te);
    }
}



// The max slope's second-order noise term (docs/algorithms/cube.md "Max slope: the plug-in
// maximum's noise term"): each half-line's max slope f = atan(s) with s = dy / (sqrt(alpha beta)
// + w - alpha - beta) (interior_max_slope) is a convex function of the fitted (alpha, beta, w,
// dy), so E[f(x^)] = f(x) + tr(f'' Cov) / 2 + O(sigma^4) (the delta method to second order).
// Returned: the mean over the valid half-lines of tr(f'' Cov) / 2 in degrees, f'' by central
// differences, Cov the fit's own (CubeHalfLine::interior_cov; dy = h_rim - CFT with CFT held,
// it is shared). A half-line with alpha or beta within 0.02 mm of 0 (f is not smooth at 0: the
// square root) or without a covariance contributes 0.
double max_slope_noise_term_deg(const std::vector<CubeHalfLine>& lines) {
    constexpr double kStep = 2e-3;       // mm: f'' to ~(kStep / alpha)^2 ~ 1e-4 relative
    constexpr double kMinHandle = 0.02;  // mm, 10 steps
    auto slope_deg = [](const Eigen::Vector4d& x) {
        const double den = std::sqrt(std::max(0.0, x(0) * x(1))) + x(2) - x(0) - x(1);
        return std::atan(x(3) / den) * kDeg;
    };
    double sum = 0.0;
    int valid = 0;
    for (const auto& h : lines) {
        if (!h.valid) continue;
        ++valid;
        const Ctrl& q = h.interior.control;
        const Eigen::Vector4d x(q[1].x() - q[0].x(), q[3].x() - q[2].x(), q[3].x() - q[0].x(),
                                q[3].y() - q[0].y());
        const Eigen::Matrix4d& cov = h.interior_cov;
        if (!cov.allFinite() || std::min(x(0), x(1)) < kMinHandle) continue;
        Eigen::Matrix4d f2;
        for (int a = 0; a < 4; ++a) {
            for (int b = 0; b < 4; ++b) {
                auto at = [&](double sa, double sb) {
                    Eigen::Vector4d y = x;
                    y(a) += sa * kStep;
                    y(b) += sb * kStep;
                    return slope_deg(y);
                };
                f2(a, b) = (at(1, 1) - at(1, -1) - at(-1, 1) + at(-1, -1)) / (4.0 * kStep * kStep);
            }
        }
        sum += 0.5 * f2.cwiseProduct(cov).sum();
    }
    return valid > 0 ? sum / valid : 0.0;
}

// The pit volume's second-order noise term (docs/algorithms/cube.md "V_p: the plug-in volume's
// noise term"): V_p = A_3D(rim) h_r - V_r (Eq. 7.29) is a smooth function of every half-line's
// fitted x_i = (alpha, beta, r_rim, h_rim) (CFT held: it is shared), so E[V_p(x^)] = V_p(x) +
// sum_i tr(H_i Cov_i) / 2 + O(sigma^4) with H_i its Hessian in x_i and Cov_i the fit's own
// covariance (CubeHalfLine::interior_cov); the half-lines' fits are independent (disjoint
// sectors), so no cross terms. H_i by central differences (step 2 um: V_p is a polynomial in x_i
// but for the rim plane's normal, so the truncation is ~(step / r_rim)^2 of a small term), the
// whole Eq. 7.29 re-evaluated: V_r's integral to each half-line's own rim, A's bilinear and
// normal terms and A's product with the mean rim height. A half-line without a covariance
// contributes 0. Returned in mm^3.
double pit_volume_noise_term_mm3(const std::vector<CubeHalfLine>& lines, const V2& centre) {
    constexpr double kStep = 2e-3;  // mm
    const std::size_t n = lines.size();
    auto point = [&](const CubeHalfLine& h, double r, double z) {
        const V2 o = std::isnan(h.origin_mm.x()) ? centre : h.origin_mm;
        const V2 q = o + r * h.direction;
        return V3(q.x(), q.y(), z);
    };
    std::vector<V3> pts;
    double h_sum = 0.0;
    double v_sum = 0.0;
    for (const auto& h : lines) {
        pts.push_back(point(h, h.rim_radius_mm, h.rim_height_mm));
        h_sum += h.rim_height_mm;
        v_sum += h.rim_volume_mm3;
    }
    const double inv_n = 1.0 / static_cast<double>(n);
    double sum = 0.0;
    for (std::size_t i = 0; i < n; ++i) {
        const CubeHalfLine& h = lines[i];
        const Eigen::Matrix4d& cov = h.interior_cov;
        if (!cov.allFinite()) continue;
        const Ctrl& q = h.interior.control;
        const Eigen::Vector4d x(q[1].x() - q[0].x(), q[3].x() - q[2].x(), q[3].x(), q[3].y());
        // V_p with half-line i's x replaced by y, every other half-line as fitted.
        auto vp = [&](const Eigen::Vector4d& y) {
            const Ctrl c{q[0], V2(q[0].x() + y(0), q[0].y()), V2(y(2) - y(1), y(3)),
                         V2(y(2), y(3))};
            std::vector<V3> p = pts;
            p[i] = point(h, y(2), y(3));
            const double vr =
                2.0 * kPi * inv_n * (v_sum - h.rim_volume_mm3 + bezier_volume_integral(c, 1.0));
            return disk(std::move(p)).area_mm2 * (h_sum - h.rim_height_mm + y(3)) * inv_n - vr;
        };
        for (int a = 0; a < 4; ++a) {
            for (int b = a; b < 4; ++b) {
                auto at = [&](double sa, double sb) {
                    Eigen::Vector4d y = x;
                    y(a) += sa * kStep;
                    y(b) += sb * kStep;
                    return vp(y);
                };
                const double d2 =
                    (at(1, 1) - at(1, -1) - at(-1, 1) + at(-1, -1)) / (4.0 * kStep * kStep);
                sum += (a == b ? 0.5 : 1.0) * d2 * cov(a, b);  // symmetric: off-diagonals twice
            }
        }
    }
    return sum;
}

void summarise_macula(CubeResult& res, const CubeParams& params) {
    const int n = static_cast<int>(res.half_lines.size());
    int valid = 0;
    int flat_count = 0;
    double rim_sum = 0.0;
    double slope_sum = 0.0;
    double flat_sum = 0.0;
    double alpha_sum = 0.0;
    double beta_sum = 0.0;
    double sse = 0.0;
    int count = 0;
    double vr = 0.0;
    double vir = 0.0;
    for (const auto& h : res.half_lines) {
        if (!h.valid) continue;
        ++valid;
        rim_sum += h.rim_height_mm;
        slope_sum += h.max_slope_deg;
        alpha_sum += h.alpha_mm;
        beta_sum += h.beta_mm;
        vr += h.rim_volume_mm3;
        vir += h.inner_rim_volume_mm3;
        if (!std::isnan(h.pit_flat_radius_mm)) {
            ++flat_count;
            flat_sum += h.pit_flat_radius_mm;
        }
        // The samples each half-line's RMSE is measured on (the bilinear ones when the fit ran on
        // sector bins): the eye's RMSE is the RMS over all of them.
        sse += h.rmse_sse_mm2;
        count += h.rmse_num_samples;
    }
    if (valid == 0) {
        throw AnalysisError("no half-line could be fitted (" + res.half_lines.front().problem +
                            "): is the fovea inside the scan?");
    }
    const double inv = 1.0 / valid;
    res.rim_height_mm = rim_sum * inv;                  // Eq. 7.15
    res.pit_depth_mm = res.rim_height_mm - res.cft_mm;  // Eq. 7.19
    res.max_pit_slope_deg = slope_sum * inv;            // Eq. 7.21 on atan(s_i)
    // Under noise (sector-bin samples) less its second-order noise term: the mean of plug-in
    // maxima is biased upward by the noise (docs/algorithms/cube.md).
    if (res.noise_adaptive_samples) res.max_pit_slope_deg -= max_slope_noise_term_deg(res.half_lines);
    res.alpha_mean_mm = alpha_sum * inv;
    res.beta_mean_mm = beta_sum * inv;
    if (flat_count == valid) res.pit_flat_diameter_mm = 2.0 * flat_sum / flat_count;  // Eq. 7.26
    res.rmse_um = 1000.0 * std::sqrt(sse / static_cast<double>(count));
    const bool all_valid = valid == n;
    if (!all_valid) {
        res.qc_flags.push_back("half-line fit failed");
        for (const auto& h : res.half_lines) {
            if (!h.valid) {
                res.notes.push_back("half-line " + std::to_string(h.angle_deg) +
                                    " deg: " + h.problem);
            }
        }
    }
    if (flat_count < valid) res.qc_flags.push_back("pit shallower than tau");
    if (!res.line_scan && all_valid) {
        std::vector<V3> rim_pts;
        std::vector<V3> slope_pts;
        std::vector<V3> flat_pts;
        for (const auto& h : res.half_lines) {
            auto pt = [&](double r, double z) {
                const V2 o = std::isnan(h.origin_mm.x()) ? res.centre_mm : h.origin_mm;
                const V2 q = o + r * h.direction;
                return V3(q.x(), q.y(), z);
            };
            rim_pts.push_back(pt(h.rim_radius_mm, h.rim_height_mm));
            slope_pts.push_back(pt(h.slope_point.x(), h.slope_point.y()));
            flat_pts.push_back(pt(h.pit_flat_radius_mm, res.cft_mm + params.tau_mm));
        }
        res.rim = disk(std::move(rim_pts));
        res.slope = disk(std::move(slope_pts));
        if (flat_count == n) res.pit_flat = disk(std::move(flat_pts));
        res.rim_volume_mm3 = 2.0 * kPi / n * vr;                                         // Eq. 7.27
        res.inner_rim_volume_mm3 = 2.0 * kPi / n * vir;                                  // Eq. 7.28
        res.pit_volume_mm3 = res.rim.area_mm2 * res.rim_height_mm - res.rim_volume_mm3;  // 7.29
        // Under noise (sector-bin samples) less its second-order noise term; a plug-in value
        // smaller than the term gives 0 (no pit), never a negative volume.
        if (res.noise_adaptive_samples && res.pit_volume_mm3 >= 0.0) {
            res.pit_volume_mm3 = std::max(
                0.0, res.pit_volume_mm3 - pit_volume_noise_term_mm3(res.half_lines, res.centre_mm));
        }
    } else if (!res.line_scan) {
        res.notes.push_back("disks and volumes need every half-line: omitted");
    }
    if (res.line_scan) {
        res.notes.push_back(
            "line scan: 2-D parameters only (docs/algorithms/cube.md); the 3-D parameters "
            "(disks, volumes) are omitted");
    }
}

void macula_qc(CubeResult& res,
               const io::Scan& scan,
               const ScanGeometry& geo,
               const CubeParams& params) {
    int missing_pit = 0;
    for (const auto& h : res.half_lines) missing_pit += h.num_missing_interior;
    if (missing_pit > 0) res.qc_flags.push_back("missing values in the pit");
    if (res.rmse_um > params.rmse_warning_um) res.qc_flags.push_back("fit RMSE high");
    // A radial scan has no parallel spacing and is oriented by its own lines (radial_qc).
    if (!res.radial_scan && !res.line_scan && geo.spacing().positions_known &&
        !geo.spacing().uniform) {
        res.qc_flags.push_back("B-scan spacing not uniform");
    }
    if (!res.radial_scan && !geo.oriented_from_positions()) {
        res.qc_flags.push_back("orientation assumed (B-scan positions unusable)");
    }
    if (!res.line_scan && scan.meta.pattern == io::ScanPattern::kUnknown) {
        res.qc_flags.push_back(res.radial_scan ? "scan pattern unknown: analysed as radial lines"
                                               : "scan pattern unknown: analysed as a volume");
        res.notes.push_back("scan pattern code " + std::to_string(scan.meta.scan_pattern_code) +
                            " is not a known Spectralis pattern; the B-scans were taken as " +
                            (res.radial_scan ? "radial lines through one crossing (they are not "
                                               "parallel)"
                                             : "a volume's parallel lines"));
    }
    if (scan.meta.laterality == io::Laterality::kUnknown) {
        res.qc_flags.push_back("eye unknown: nasal assumed on SLO +x");
    }
    if (res.map.num_outside_image > 0) {
        res.qc_flags.push_back("segmentation outside the image");
        res.notes.push_back(std::to_string(res.map.num_outside_image) +
                            " A-scans with the ILM or BM outside the image: missing");
    }
    if (res.map.num_inverted > 0) {
        res.qc_flags.push_back("ILM below BM");
        res.notes.push_back(std::to_string(res.map.num_inverted) +
                            " A-scans with the ILM below the BM: missing");
    }
}

void check_macula_result(const CubeResult& res, const io::Scan& scan) {
    const double depth_mm = scan.meta.size_z > 0 ? scan.meta.size_z * scan.meta.scale_z_mm
                                                 : std::numeric_limits<double>::infinity();
    const double width = (res.map.cols - 1) * res.map.dx_mm;
    const double height = (res.map.rows - 1) * res.map.dy_mm;
    const double diagonal = std::hypot(width, height);
    const auto refuse = [](const std::string& what, double v, const std::string& expected) {
        std::ostringstream s;
        s.precision(6);
        s << "impossible result: " << what << " " << v << " (expected " << expected
          << "): the segmentation does not describe a fovea";
        throw AnalysisError(s.str());
    };
    const auto in_depth = [&](const std::string& what, double v) {
        if (!(std::isfinite(v) && v > 0.0 && v <= depth_mm)) {
            refuse(what, v, "in (0, " + std::to_string(depth_mm) + "] mm, the image depth");
        }
    };
    in_depth("CFT", res.cft_mm);
    in_depth("rim height", res.rim_height_mm);
    if (!(res.pit_depth_mm >= 0.0)) refuse("pit depth", res.pit_depth_mm, ">= 0 mm");
    if (!std::isfinite(res.rmse_um)) refuse("fit RMSE", res.rmse_um, "finite");
    if (!(res.max_pit_slope_deg >= 0.0 && res.max_pit_slope_deg < 90.0)) {
        refuse("maximum pit slope", res.max_pit_slope_deg, "in [0, 90) deg");
    }
    // Volumes and disks are NaN when omitted (line scans, failed half-lines): checked when given.
    const auto non_negative = [&](const std::string& what, double v) {
        if (!std::isnan(v) && !(v >= 0.0 && std::isfinite(v))) refuse(what, v, ">= 0");
    };
    non_negative("rim volume (mm3)", res.rim_volume_mm3);
    non_negative("inner rim volume (mm3)", res.inner_rim_volume_mm3);
    non_negative("pit volume (mm3)", res.pit_volume_mm3);
    for (const auto& [what, d] : {std::pair<const char*, const CubeDisk*>{"rim", &res.rim},
                                  {"slope", &res.slope},
                                  {"pit-flat", &res.pit_flat}}) {
        if (std::isnan(d->diameter_mm)) continue;
        if (!(d->diameter_mm >= 0.0 && d->diameter_mm <= diagonal)) {
            refuse(std::string(what) + " disk diameter (mm)", d->diameter_mm,
                   "within the scan's diagonal, " + std::to_string(diagonal) + " mm");
        }
        non_negative(std::string(what) + " disk area (mm2)", d->area_mm2);
    }
}

}  // namespace cube_detail

CubeDisk cube_disk(std::vector<Eigen::Vector3d> points) { return disk(std::move(points)); }

}  // namespace octshape::retina
