// Axial registration of an ONH scan's B-scans (docs/algorithms/onh.md, "Axial registration").

#include "octshape/retina/axial_registration.h"

#include <algorithm>
#include <cmath>
#include <string>

#include <Eigen/Dense>

#include "octshape/error.h"
#include "octshape/retina/radial_geometry.h"
#include "octshape/retina/report_util.h"

namespace octshape::retina {
namespace {

// One BM value: its B-scan, grid position (normalised) and depth (px).
struct BmSample {
    int bscan = 0;
    double x = 0.0;
    double y = 0.0;
    double depth = 0.0;
};

// Monomials x^i y^j, 1 <= i + j <= degree; `skip_pure_y`: without i = 0 (a volume's offsets
// already hold every function of y).
std::vector<std::pair<int, int>> monomials(int degree, bool skip_pure_y) {
    std::vector<std::pair<int, int>> m;
    for (int d = 1; d <= degree; ++d) {
        for (int i = d; i >= 0; --i) {
            if (skip_pure_y && i == 0) continue;
            m.emplace_back(i, d - i);
        }
    }
    return m;
}

// The BM values of the scan at normalised grid positions (centred on the field, unit = half
// its extent, so the polynomial is well conditioned). Volumes: x = A-scan * ScaleX, y = B-scan
// * Distance; radial scans: the lines' A-scans about their crossing.
std::vector<BmSample> bm_samples(const io::Scan& scan, bool radial, std::vector<double>& y_of_bscan) {
    const int nb = scan.num_bscans();
    const int nx = scan.meta.size_x;
    const int bm = static_cast<int>(io::Layer::kBM);
    std::vector<BmSample> out;
    y_of_bscan.assign(static_cast<std::size_t>(nb), 0.0);
    if (radial) {
        const RadialGeometry g = radial_geometry(scan);
        const double half = std::max(1e-6, 0.5 * g.mean_length_mm);
        for (int b = 0; b < nb; ++b) {
            for (int a = 0; a < nx; ++a) {
                const float d = scan.depth_px(bm, b, a);
                if (!io::is_valid(d)) continue;
                const Eigen::Vector2d p = g.ascan_mm(b, a, nx);
                out.push_back({b, p.x() / half, p.y() / half, d});
            }
        }
        return out;
    }
    const double w = 0.5 * std::max(1e-6, (nx - 1) * scan.meta.scale_x_mm);
    const double h = 0.5 * std::max(1e-6, (nb - 1) * scan.meta.distance_mm);
    for (int b = 0; b < nb; ++b) {
        y_of_bscan[static_cast<std::size_t>(b)] = (b * scan.meta.distance_mm - h) / h;
        for (int a = 0; a < nx; ++a) {
            const float d = scan.depth_px(bm, b, a);
            if (!io::is_valid(d)) continue;
            out.push_back({b, (a * scan.meta.scale_x_mm - w) / w,
                           y_of_bscan[static_cast<std::size_t>(b)], d});
        }
    }
    return out;
}

double monomial(const std::pair<int, int>& m, double x, double y) {
    return std::pow(x, m.first) * std::pow(y, m.second);
}

// Weighted fit of per-B-scan offsets plus the surface terms (the offsets eliminated: every
// B-scan's samples centred on their weighted mean). Returns the offsets (NaN where a B-scan has
// no weight) and fills the surface coefficients.
std::vector<double> fit_offsets(const std::vector<BmSample>& s, const std::vector<double>& w,
                                const Eigen::MatrixXd& Phi,  // samples x terms
                                const std::vector<char>& use_bscan, int nb,
                                Eigen::VectorXd& beta) {
    const Eigen::Index k = Phi.cols();
    std::vector<double> sw(static_cast<std::size_t>(nb), 0.0);
    std::vector<double> sd(static_cast<std::size_t>(nb), 0.0);
    Eigen::MatrixXd sphi = Eigen::MatrixXd::Zero(k, nb);
    // At most 14 terms (degree 4): fixed-capacity vectors, no allocation per sample.
    using VecK = Eigen::Matrix<double, Eigen::Dynamic, 1, Eigen::ColMajor, 16, 1>;
    VecK phi(k);
    for (std::size_t i = 0; i < s.size(); ++i) {
        const auto b = static_cast<std::size_t>(s[i].bscan);
        if (!use_bscan[b] || w[i] <= 0.0) continue;
        phi = Phi.row(static_cast<Eigen::Index>(i)).transpose();
        sw[b] += w[i];
        sd[b] += w[i] * s[i].depth;
        sphi.col(static_cast<Eigen::Index>(b)) += w[i] * phi;
    }
    Eigen::MatrixXd A = Eigen::MatrixXd::Zero(k, k);
    Eigen::VectorXd r = Eigen::VectorXd::Zero(k);
    for (std::size_t i = 0; i < s.size(); ++i) {
        const auto b = static_cast<std::size_t>(s[i].bscan);
        if (!use_bscan[b] || w[i] <= 0.0 || sw[b] <= 0.0) continue;
        phi = Phi.row(static_cast<Eigen::Index>(i)).transpose();
        const VecK c = phi - sphi.col(static_cast<Eigen::Index>(b)) / sw[b];
        A.noalias() += w[i] * c * c.transpose();
        r += w[i] * (s[i].depth - sd[b] / sw[b]) * c;
    }
    beta = k > 0 ? Eigen::VectorXd(A.ldlt().solve(r)) : Eigen::VectorXd();
    if (k > 0 && !beta.allFinite()) beta = A.completeOrthogonalDecomposition().solve(r);
    std::vector<double> offset(static_cast<std::size_t>(nb), std::numeric_limits<double>::quiet_NaN());
    for (int b = 0; b < nb; ++b) {
        const auto bi = static_cast<std::size_t>(b);
        if (sw[bi] > 0.0) offset[bi] = (sd[bi] - sphi.col(b).dot(beta)) / sw[bi];
    }
    return offset;
}

// The part of the offsets a polynomial of `degree` in y cannot explain (volumes), or the
// offsets about their mean (radial scans); weighted by each B-scan's sample count. `fixed_y2`
// (volumes, finite): the polynomial's y^2 coefficient is this value (the eye's curvature across
// the B-scans taken from its curvature along them), the other coefficients are fitted.
std::vector<double> motion_of(const std::vector<double>& offset, const std::vector<double>& y,
                              const std::vector<double>& count, int degree, bool radial,
                              double fixed_y2, double* y2_out = nullptr) {
    const std::size_t nb = offset.size();
    const bool fix = !radial && degree >= 2 && std::isfinite(fixed_y2);
    const int k = radial ? 1 : degree + 1;
    auto power = [&](double yb, int t) { return std::pow(yb, fix && t >= 2 ? t + 1 : t); };
    const int kf = fix ? k - 1 : k;  // fitted: y^0, y^1, y^3, ... when y^2 is fixed
    const double y2 = fix ? fixed_y2 : 0.0;
    Eigen::MatrixXd A = Eigen::MatrixXd::Zero(kf, kf);
    Eigen::VectorXd r = Eigen::VectorXd::Zero(kf);
    Eigen::VectorXd phi(kf);
    for (std::size_t b = 0; b < nb; ++b) {
        if (!std::isfinite(offset[b])) continue;
        for (int t = 0; t < kf; ++t) phi(t) = power(y[b], t);
        A.noalias() += count[b] * phi * phi.transpose();
        r += count[b] * (offset[b] - y2 * y[b] * y[b]) * phi;
    }
    const Eigen::VectorXd c = A.completeOrthogonalDecomposition().solve(r);
    if (y2_out != nullptr) *y2_out = fix ? y2 : (k > 2 ? c(2) : 0.0);
    std::vector<double> m(nb, std::numeric_limits<double>::quiet_NaN());
    for (std::size_t b = 0; b < nb; ++b) {
        if (!std::isfinite(offset[b])) continue;
        for (int t = 0; t < kf; ++t) phi(t) = power(y[b], t);
        m[b] = offset[b] - y2 * y[b] * y[b] - phi.dot(c);
    }
    return m;
}

// Fills the NaN entries linearly from the nearest finite neighbours in B-scan order (the end
// ones from the nearest); all NaN stays all NaN.
void interpolate_gaps(std::vector<double>& v) {
    const int n = static_cast<int>(v.size());
    for (int i = 0; i < n; ++i) {
        if (std::isfinite(v[static_cast<std::size_t>(i)])) continue;
        int lo = i - 1;
        while (lo >= 0 && !std::isfinite(v[static_cast<std::size_t>(lo)])) --lo;
        int hi = i + 1;
        while (hi < n && !std::isfinite(v[static_cast<std::size_t>(hi)])) ++hi;
        if (lo < 0 && hi >= n) return;
        if (lo < 0) v[static_cast<std::size_t>(i)] = v[static_cast<std::size_t>(hi)];
        else if (hi >= n) v[static_cast<std::size_t>(i)] = v[static_cast<std::size_t>(lo)];
        else {
            const double f = static_cast<double>(i - lo) / (hi - lo);
            v[static_cast<std::size_t>(i)] = (1.0 - f) * v[static_cast<std::size_t>(lo)] +
                                             f * v[static_cast<std::size_t>(hi)];
        }
    }
}

}  // namespace

void AxialRegistrationParams::validate() const {
    auto require = [](bool ok, const char* field, const char* why) {
        if (!ok) throw UsageError(std::string("axial registration: ") + field + " " + why);
    };
    require(surface_degree >= 1 && surface_degree <= 4, "surface_degree", "must be in 1..4");
    require(std::isfinite(large_motion_um) && large_motion_um > 0.0, "large_motion_um",
            "must be positive");
    require(std::isfinite(max_residual_um) && max_residual_um > 0.0, "max_residual_um",
            "must be positive");
    require(min_bm_fraction > 0.0 && min_bm_fraction < 1.0, "min_bm_fraction", "must be in (0, 1)");
    require(std::isfinite(max_curvature_mrw_um) && max_curvature_mrw_um > 0.0,
            "max_curvature_mrw_um", "must be positive");
}

AxialRegistration estimate_axial_motion(const io::Scan& scan, const AxialRegistrationParams& params) {
    params.validate();
    AxialRegistration R;
    R.enabled = params.enabled;
    R.surface_degree = params.surface_degree;
    const int nb = scan.num_bscans();
    const int nx = scan.meta.size_x;
    const double um_per_px = scan.meta.scale_z_mm * 1000.0;
    const bool radial = is_radial_scan(scan);
    std::vector<double> y;
    const std::vector<BmSample> s = bm_samples(scan, radial, y);
    std::vector<double> count(static_cast<std::size_t>(nb), 0.0);
    for (const BmSample& p : s) count[static_cast<std::size_t>(p.bscan)] += 1.0;
    const double need = std::max(10.0, params.min_bm_fraction * nx);
    std::vector<char> use(static_cast<std::size_t>(nb), 0);
    int usable = 0;
    for (int b = 0; b < nb; ++b) {
        use[static_cast<std::size_t>(b)] = count[static_cast<std::size_t>(b)] >= need ? 1 : 0;
        usable += use[static_cast<std::size_t>(b)];
    }
    R.shift_um.assign(static_cast<std::size_t>(nb), 0.0);
    R.estimated.assign(static_cast<std::size_t>(nb), false);
    const auto terms = monomials(params.surface_degree, !radial);
    if (usable < std::max(3, radial ? 3 : params.surface_degree + 2)) {
        R.qc_flags.push_back("axial motion not estimated (too little BM)");
        R.notes.push_back("axial registration: " + std::to_string(usable) + " of " +
                          std::to_string(nb) + " B-scans hold enough BM; nothing was shifted");
        return R;
    }
    // Robust fit: Tukey's biweight, the scale from the median absolute residual.
    std::vector<double> w(s.size(), 1.0);
    std::vector<double> offset;
    Eigen::VectorXd beta;
    std::vector<double> res(s.size(), 0.0);
    Eigen::MatrixXd Phi(static_cast<Eigen::Index>(s.size()), static_cast<Eigen::Index>(terms.size()));
    for (std::size_t i = 0; i < s.size(); ++i) {
        for (std::size_t t = 0; t < terms.size(); ++t) {
            Phi(static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(t)) = monomial(terms[t], s[i].x, s[i].y);
        }
    }
    for (int iter = 0; iter < 8; ++iter) {
        offset = fit_offsets(s, w, Phi, use, nb, beta);
        std::vector<double> absr;
        absr.reserve(s.size());
        for (std::size_t i = 0; i < s.size(); ++i) {
            const double o = offset[static_cast<std::size_t>(s[i].bscan)];
            const double f = o + Phi.row(static_cast<Eigen::Index>(i)).dot(beta);
            res[i] = std::isfinite(o) ? s[i].depth - f : std::numeric_limits<double>::quiet_NaN();
            if (std::isfinite(res[i])) absr.push_back(std::fabs(res[i]));
        }
        if (absr.empty()) break;
        std::nth_element(absr.begin(), absr.begin() + static_cast<std::ptrdiff_t>(absr.size() / 2), absr.end());
        // Scale floor 0.5 px: segmentation lines are quantised near a pixel.
        const double c = 4.685 * std::max(0.5, 1.4826 * absr[absr.size() / 2]);
        for (std::size_t i = 0; i < s.size(); ++i) {
            const double u = std::isfinite(res[i]) ? res[i] / c : 1.0;
            w[i] = std::fabs(u) < 1.0 ? (1.0 - u * u) * (1.0 - u * u) : 0.0;
        }
    }
    double ss = 0.0;
    double sw = 0.0;
    for (std::size_t i = 0; i < s.size(); ++i) {
        if (w[i] > 0.0) {
            ++R.bm_values_used;
            ss += res[i] * res[i];
            sw += 1.0;
        } else {
            ++R.bm_values_rejected;
        }
    }
    R.residual_rms_um = sw > 0.0 ? std::sqrt(ss / sw) * um_per_px : 0.0;
    // The isotropic eye wall (volumes): the offsets' curvature across the B-scans is the
    // motion's as well as the eye's and cannot be told apart from them, so the eye's is taken
    // from its curvature along the B-scans, S's x^2 term (normalised units: x by the half width
    // w, y by the half height h, so the same curvature is the x^2 coefficient times (h / w)^2).
    double fixed_y2 = std::numeric_limits<double>::quiet_NaN();
    if (!radial && params.isotropic_curvature && params.surface_degree >= 2) {
        for (std::size_t t = 0; t < terms.size(); ++t) {
            if (terms[t] == std::make_pair(2, 0)) fixed_y2 = beta(static_cast<Eigen::Index>(t));
        }
        const double half_w = 0.5 * std::max(1e-6, (nx - 1) * scan.meta.scale_x_mm);
        const double half_h = 0.5 * std::max(1e-6, (nb - 1) * scan.meta.distance_mm);
        fixed_y2 *= (half_h / half_w) * (half_h / half_w);
        // What the prior gives to the motion: the free fit's y^2 coefficient minus the fixed one.
        double free_y2 = 0.0;
        (void)motion_of(offset, y, count, params.surface_degree, radial,
                        std::numeric_limits<double>::quiet_NaN(), &free_y2);
        R.curvature_to_motion_um = (free_y2 - fixed_y2) * um_per_px;
        R.field_half_height_mm = half_h;
    }
    std::vector<double> m = motion_of(offset, y, count, params.surface_degree, radial, fixed_y2);
    for (int b = 0; b < nb; ++b) {
        const auto bi = static_cast<std::size_t>(b);
        R.estimated[bi] = std::isfinite(m[bi]);
        if (!R.estimated[bi]) ++R.bscans_not_estimated;
    }
    interpolate_gaps(m);
    double sum2 = 0.0;
    for (int b = 0; b < nb; ++b) {
        const auto bi = static_cast<std::size_t>(b);
        R.shift_um[bi] = m[bi] * um_per_px;
        sum2 += R.shift_um[bi] * R.shift_um[bi];
        R.max_abs_shift_um = std::max(R.max_abs_shift_um, std::fabs(R.shift_um[bi]));
    }
    R.rms_shift_um = std::sqrt(sum2 / std::max(1, nb));
    R.applied = params.enabled;
    const std::string what = params.enabled ? "removed" : "not removed (registration off)";
    R.notes.push_back("axial motion between B-scans " + what + ": RMS " +
                      fixed_number(R.rms_shift_um, 1) + " um, largest " +
                      fixed_number(R.max_abs_shift_um, 1) + " um; BM about its smooth surface " +
                      fixed_number(R.residual_rms_um, 1) + " um RMS (" +
                      std::to_string(R.bm_values_rejected) + " BM values rejected)");
    if (R.rms_shift_um > params.large_motion_um) {
        R.qc_flags.push_back(params.enabled ? "large axial motion between B-scans (registered)"
                                            : "large axial motion between B-scans (not registered)");
    }
    if (R.bscans_not_estimated > 0) {
        R.qc_flags.push_back("axial motion not estimated in some B-scans (too little BM)");
        R.notes.push_back("axial registration: " + std::to_string(R.bscans_not_estimated) +
                          " B-scans without enough BM took their neighbours' shift");
    }
    if (R.residual_rms_um > params.max_residual_um) {
        R.qc_flags.push_back("BM is not one smooth surface: axial registration uncertain");
    }
    return R;
}

void apply_axial_registration(io::Scan& scan, const AxialRegistration& registration) {
    if (!registration.applied) return;
    const double um_per_px = scan.meta.scale_z_mm * 1000.0;
    for (int b = 0; b < scan.num_bscans(); ++b) {
        const double dz = -registration.shift_um[static_cast<std::size_t>(b)] / um_per_px;
        io::BScan& bs = scan.bscans[static_cast<std::size_t>(b)];
        // The lines by the shift itself (below 1e-3 px, 4 nm, numerically zero: as read).
        if (std::fabs(dz) >= 1e-3) {
            std::vector<float> pixels;
            pixels.swap(bs.pixels);
            io::shift_bscan(bs, scan.meta.size_x, scan.meta.size_z, dz);
            pixels.swap(bs.pixels);
        }
        // The pixels by whole rows: a fractional shift blends neighbouring rows, which smooths
        // the speckle of the moved B-scans alone (and their edges) and moves the level set.
        // The lines stay within half a pixel of the pixels' content, the level set's own
        // resolution (docs/algorithms/onh.md, "Axial registration").
        const double whole = std::round(dz);
        if (whole != 0.0 && !bs.pixels.empty()) {
            std::vector<std::vector<float>> seg;
            seg.swap(bs.seg);
            io::shift_bscan(bs, scan.meta.size_x, scan.meta.size_z, whole);
            seg.swap(bs.seg);
        }
        // What the lines moved beyond the pixels: the level set, which reads the pixels, moves
        // its result by it into the lines' frame (docs/algorithms/onh.md, "Applied").
        if (std::fabs(dz) >= 1e-3) {
            bs.line_offset_px += dz - (bs.pixels.empty() ? 0.0 : whole);
        }
    }
}

void register_bmo_points(std::vector<BmoPoint>& points, const io::Scan& scan,
                         const AxialRegistration& registration) {
    if (!registration.applied || registration.shift_um.empty()) return;
    const int nb = static_cast<int>(registration.shift_um.size());
    for (BmoPoint& p : points) {
        const int b = bscan_of_bmo_point(p, scan);
        if (b < 0 || b >= nb) continue;
        // The B-scan's content moves up by its shift: heights (z = -depth) rise by it.
        p.mm.z() += registration.shift_um[static_cast<std::size_t>(b)] * 1e-3;
    }
}

int bscan_of_bmo_point(const BmoPoint& point, const io::Scan& scan) {
    if (point.bscan >= 0) return point.bscan;
    if (scan.meta.distance_mm > 0.0) {
        return static_cast<int>(std::lround(point.mm.y() / scan.meta.distance_mm));
    }
    return -1;
}

void assess_curvature_mrw_effect(AxialRegistration& registration,
                                 const std::vector<Eigen::Vector3d>& bmo_points_mm,
                                 const std::vector<Eigen::Vector3d>& mrw_points_mm,
                                 const AxialRegistrationParams& params) {
    params.validate();
    const double h = registration.field_half_height_mm;
    if (!(h > 0.0) || registration.curvature_to_motion_um == 0.0) return;
    const double C = registration.curvature_to_motion_um;
    auto c = [&](double y_mm) { return C * ((y_mm - h) / h) * ((y_mm - h) / h); };
    double sum = 0.0;
    int n = 0;
    for (std::size_t i = 0; i < bmo_points_mm.size() && i < mrw_points_mm.size(); ++i) {
        const Eigen::Vector3d& P = bmo_points_mm[i];
        const Eigen::Vector3d& Q = mrw_points_mm[i];
        const double len = (Q - P).norm();
        if (!P.allFinite() || !Q.allFinite() || !(len > 0.0)) continue;
        sum += (Q.z() - P.z()) / len * (c(Q.y()) - c(P.y()));
        ++n;
    }
    registration.curvature_mrw_effect_um = n > 0 ? std::fabs(sum / n) : 0.0;
    // A wall curved differently across the B-scans than along them (a staphyloma, a tilted
    // disc) looks to the BM exactly like a curved motion, so no bound tells them apart; past the
    // MRW's 5 um the result is uncertain beyond its tolerance either way, so say so (random
    // walks of 100 um SD leave a median 2.0 um of MRW on a 4.35 mm field; docs/algorithms/
    // onh.md "Curved motion across B-scans").
    if (registration.curvature_mrw_effect_um > params.max_curvature_mrw_um) {
        registration.qc_flags.push_back(
            "eye wall curves differently across and along the B-scans: curvature removed as "
            "motion may be the eye's (3-D MRW uncertain by about " +
            fixed_number(registration.curvature_mrw_effect_um, 0) + " um)");
    }
}

AxialRegistration register_axially(io::Scan& scan, const AxialRegistrationParams& params) {
    AxialRegistration r = estimate_axial_motion(scan, params);
    apply_axial_registration(scan, r);
    return r;
}

void register_bmo_points_laterally(std::vector<BmoPoint>& points, const io::Scan& scan,
                                   const LateralRegistration& registration) {
    if (!registration.applied || registration.shift_um.empty()) return;
    const int nb = static_cast<int>(registration.shift_um.size());
    for (BmoPoint& p : points) {
        const int b = bscan_of_bmo_point(p, scan);
        if (b < 0 || b >= nb) continue;
        // The B-scan's content moves towards lower A-scans by its shift.
        p.mm.x() -= registration.shift_um[static_cast<std::size_t>(b)] * 1e-3;
    }
}

}  // namespace octshape::retina
