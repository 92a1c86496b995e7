// Information limit of the CuBe analysis under segmentation noise (issue 3; docs/algorithms/
// cube.md, Accuracy, "Information limit"): the Cramer-Rao lower bound (CRB) of every parameter
// for the thesis's per-half-line model, fitted jointly to every thickness node within R, beside
// the analysis's own RMS error over noisy seeds of the same phantom.
//
// Model (the natural continuous extension of the per-half-line CuBe model, §7.1-7.2):
//   T(x, y; theta) = (1 - w) T_i(r) + w T_{i+1}(r),  r = |(x, y) - c|, phi = anatomical angle,
//   phi = (i + w) 360 / n, T_i the half-line i's profile: the interior cubic (Eq. 7.5)
//   P0 = (0, CFT), P1 = (alpha_i, CFT), P2 = (w_i - beta_i, h_i), P3 = (w_i, h_i) for r <= w_i and
//   the exterior (Eq. 7.6) P0 = (w_i, h_i), P1 = (w_i + alpha_ext_i, h_i), P2 = (p2x_i, p2y_i),
//   P3 = (R, p3y_i) beyond, as cube.cpp parameterises them (the CFT shared, P0 = (0, CFT)).
//   theta = (CFT, 8 per half-line, centre offset (dx, dy)): 1 + 8 n + 2 unknowns.
// Truth theta*: the phantom's own per-direction profile at the half-line angles (the Bezier
// phantom is exactly CuBe in every direction; the exterior is its sub-arc on [rim, R], as
// macula_truth gives it). Between half-lines the phantom interpolates its parameters, not its
// profiles, so the model surface differs slightly from the phantom's (printed: "mismatch").
// Noise: the phantom draws N(0, noise_um) on ILM and on BM independently at every A-scan, so the
// thickness node noise is independent with SD sqrt(2) noise_um = 3.8717 um (1 axial pixel).
// Fisher information J = sum over every grid node within R of grad T grad T^T / sigma^2
// (central differences, step h; the table is recomputed with h / 2 and the largest relative
// change printed); CRB of a derived parameter g: grad g^T J^-1 grad g, grad g by central
// differences of the analysis's parameter formulas (docs/algorithms/cube.md, Parameters;
// interior_max_slope, bezier_point and bezier_volume_integral are the analysis's own functions,
// the disk area/diameter, pit-flat and mean formulas are restated here and checked against both
// the phantom's truth and the analysis's output).
//
// Usage: macula_crb [SEEDS [FIT_SEEDS]]   (SEEDS default 36: noisy analyses per grid for the
// estimator's RMS, seeds 7, 8, ... as bench/macula_accuracy; 0 = the bound only. FIT_SEEDS
// default 0: a joint least-squares fit of the model itself on that many seeds, ~1 s each at 193
// B-scans, to see whether the bound is attained.)
//        macula_crb bias [REALISATIONS [PX...]] [--bscans=N] [--true-centre] [--diagnose]
// (the bias table at 61 B-scans, or N, 0.5 / 1 / 2 px per surface unless PX are given; see
// bias_table; the oracle and the noise terms' diagnosis: NoiseTermProbe)
//        macula_crb centre   (the noise-free centre offset against the centre window; centre_table)

#include <Eigen/Core>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <numbers>
#include <optional>
#include <string>
#include <vector>

#include "fixtures/fisher.h"
#include "octshape/retina/cube.h"
#include "octshape/retina/phantom_common.h"
#include "octshape/retina/phantom_macula.h"

namespace {

using namespace octshape::retina;
using octshape::fisher::central_gradient;
using octshape::fisher::crb_covariance;
using octshape::fisher::crb_variance;
using octshape::fisher::FisherAccumulator;
using octshape::fisher::without;
using V2 = Eigen::Vector2d;
using V3 = Eigen::Vector3d;
using Ctrl = std::array<V2, 4>;

constexpr double kPi = std::numbers::pi;
constexpr double kDegPerRad = 180.0 / kPi;
constexpr double kSigmaUm = 3.8717;  // thickness node SD: 1 axial pixel (sqrt(2) x ILM/BM SD)

// Per-half-line unknowns.
enum LineParam { kAlpha, kBeta, kRimR, kRimH, kAlphaExt, kP2x, kP2y, kP3y, kLineParams };

struct Model {
    int n = 24;
    double radius_mm = 2.0;  // R
    double tau_mm = 0.005;
    double inner_radius_mm = 0.5;
    V2 centre = V2::Zero();  // true fovea centre, grid mm
    phantom::GridFrame frame;
    std::vector<V2> dir;  // grid direction of each half-line
    [[nodiscard]] int size() const { return 1 + kLineParams * n + 2; }
    [[nodiscard]] int line(int i, int k) const { return 1 + kLineParams * i + k; }
    [[nodiscard]] int centre_index(int axis) const { return 1 + kLineParams * n + axis; }
};

// One half-line's profile unknowns with the shared CFT.
struct Line {
    double cft = 0.0;
    std::array<double, kLineParams> q{};
};

Line line_of(const Eigen::VectorXd& th, const Model& m, int i) {
    Line l;
    l.cft = th(0);
    for (int k = 0; k < kLineParams; ++k) l.q[static_cast<std::size_t>(k)] = th(m.line(i, k));
    return l;
}

Ctrl interior(const Line& l) {
    const double w = l.q[kRimR];
    const double h = l.q[kRimH];
    return {V2(0.0, l.cft), V2(l.q[kAlpha], l.cft), V2(w - l.q[kBeta], h), V2(w, h)};  // Eq. 7.5
}

Ctrl exterior(const Line& l, double radius) {
    const double w = l.q[kRimR];
    const double h = l.q[kRimH];
    return {V2(w, h), V2(w + l.q[kAlphaExt], h), V2(l.q[kP2x], l.q[kP2y]),
            V2(radius, l.q[kP3y])};  // Eq. 7.6
}

double profile(const Line& l, double radius, double r) {
    const Ctrl c = r <= l.q[kRimR] ? interior(l) : exterior(l, radius);
    return bezier_point(c, bezier_t_at_x(c, r)).y();
}

// The model surface at grid node g.
double surface(const Eigen::VectorXd& th, const Model& m, const V2& g) {
    const V2 d = g - m.centre - V2(th(m.centre_index(0)), th(m.centre_index(1)));
    const double r = d.norm();
    const double s = m.frame.anatomical_angle_deg(d.x(), d.y()) * m.n / 360.0;
    const int i0 = static_cast<int>(std::floor(s)) % m.n;
    const double w = s - std::floor(s);
    const int i1 = (i0 + 1) % m.n;
    return (1.0 - w) * profile(line_of(th, m, i0), m.radius_mm, r) +
           w * profile(line_of(th, m, i1), m.radius_mm, r);
}

// ---- Derived parameters (docs/algorithms/cube.md, Parameters) ------------------------------

struct Param {
    const char* name;
    const char* unit;
    double scale;  // mm -> unit
};
const std::vector<Param> kParams{
    {"cft", "um", 1e3},
    {"rim_height", "um", 1e3},
    {"pit_depth", "um", 1e3},
    {"rim_diameter", "um", 1e3},
    {"rim_area", "mm2", 1.0},
    {"max_slope", "deg", 1.0},
    {"slope_diameter", "um", 1e3},
    {"slope_area", "mm2", 1.0},
    {"flat_diameter", "um", 1e3},
    {"flat_area", "mm2", 1.0},
    {"rim_volume", "mm3", 1.0},
    {"inner_rim_volume", "mm3", 1.0},
    {"pit_volume", "mm3", 1.0},
    {"alpha_mean", "um", 1e3},
    {"beta_mean", "um", 1e3},
};

// Every parameter of kParams (mm, mm2, mm3, deg) from the interior curves of the n half-lines.
std::vector<double> derived(const std::vector<Ctrl>& in, const Model& m) {
    const int n = m.n;
    const double cft = in.front()[0].y();
    double rim_h = 0.0, slope = 0.0, flat = 0.0, vr = 0.0, vir = 0.0, am = 0.0, bm = 0.0;
    std::vector<V3> rim_pts, slope_pts, flat_pts;
    for (int i = 0; i < n; ++i) {
        const Ctrl& q = in[static_cast<std::size_t>(i)];
        const double dy = q[3].y() - q[0].y();
        rim_h += q[3].y();
        am += q[1].x() - q[0].x();
        bm += q[3].x() - q[2].x();
        const MaxSlope ms = interior_max_slope(q);
        slope += std::atan(ms.slope) * kDegPerRad;  // Eq. 7.20-7.21
        const V2 sp = bezier_point(q, ms.t);        // Eq. 7.22
        // Pit flat (Eq. 7.24-7.25 on the interior): dy (3t^2 - 2t^3) = tau.
        double lo = 0.0;
        double hi = 1.0;
        for (int it = 0; it < 200; ++it) {
            const double mid = 0.5 * (lo + hi);
            if (mid == lo || mid == hi) break;
            (mid * mid * (3.0 - 2.0 * mid) < m.tau_mm / dy ? lo : hi) = mid;
        }
        const double rf = bezier_point(q, 0.5 * (lo + hi)).x();
        flat += rf;
        vr += bezier_volume_integral(q, 1.0);                             // Eq. 7.27
        // Eq. 7.28 (r_u < w)
        vir += bezier_volume_integral(q, bezier_t_at_x(q, m.inner_radius_mm));
        const V2& u = m.dir[static_cast<std::size_t>(i)];
        auto pt = [&](double r, double z) {
            return V3(m.centre.x() + r * u.x(), m.centre.y() + r * u.y(), z);
        };
        rim_pts.push_back(pt(q[3].x(), q[3].y()));
        slope_pts.push_back(pt(sp.x(), sp.y()));
        flat_pts.push_back(pt(rf, cft + m.tau_mm));
    }
    const double inv = 1.0 / n;
    const CubeDisk rd = cube_disk(rim_pts);
    const CubeDisk sd = cube_disk(slope_pts);
    const CubeDisk fd = cube_disk(flat_pts);
    const double v_r = 2.0 * kPi * inv * vr;
    return {cft,
            rim_h * inv,
            rim_h * inv - cft,
            rd.diameter_mm,
            rd.area_mm2,
            slope * inv,
            sd.diameter_mm,
            sd.area_mm2,
            2.0 * flat * inv,
            fd.area_mm2,
            v_r,
            2.0 * kPi * inv * vir,
            rd.area_mm2 * rim_h * inv - v_r,
            am * inv,
            bm * inv};
}

std::vector<double> derived(const Eigen::VectorXd& th, const Model& m) {
    std::vector<Ctrl> in;
    for (int i = 0; i < m.n; ++i) in.push_back(interior(line_of(th, m, i)));
    return derived(in, m);
}

double value(double v) { return v; }
double value(const std::optional<double>& v) { return *v; }

// Per half-line, the Hessian of kParams[k] (this bench's own formulas) in the half-line's
// x = (alpha, beta, r_rim, h_rim) at theta (CFT and the other half-lines held), by central
// differences with the analysis's step (2 um): the second-order noise term of a plug-in
// parameter is sum_i tr(H_i Cov_i) / 2 (docs/algorithms/cube.md, "V_p: the plug-in volume's
// noise term").
std::vector<Eigen::Matrix4d> line_hessians(const Eigen::VectorXd& th, const Model& m,
                                           std::size_t k) {
    constexpr double kStep = 2e-3;
    const std::array<int, 4> ix{kAlpha, kBeta, kRimR, kRimH};
    std::vector<Eigen::Matrix4d> out;
    for (int i = 0; i < m.n; ++i) {
        Eigen::Matrix4d h;
        for (int a = 0; a < 4; ++a) {
            for (int b = a; b < 4; ++b) {
                auto at = [&](double sa, double sb) {
                    Eigen::VectorXd y = th;
                    y(m.line(i, ix[static_cast<std::size_t>(a)])) += sa * kStep;
                    y(m.line(i, ix[static_cast<std::size_t>(b)])) += sb * kStep;
                    return derived(y, m)[k];
                };
                h(a, b) = h(b, a) =
                    (at(1, 1) - at(1, -1) - at(-1, 1) + at(-1, -1)) / (4.0 * kStep * kStep);
            }
        }
        out.push_back(h);
    }
    return out;
}

// `bias --diagnose`: where a plug-in volume's bias under noise comes from. Over the
// realisations whose every half-line was fitted: the plug-in V_p (Eq. 7.29 without its noise
// term), the analysis's term, and the term sum_i tr(H_i C_i) / 2 with C_i the fits' own mean
// covariance (what the analysis uses) or the realisations' covariance of the fitted
// (alpha, beta, r_rim, h_rim) (what the delta method needs); V_IR's term likewise.
struct NoiseTermProbe {
    std::vector<Eigen::Vector4d> sum = std::vector<Eigen::Vector4d>(24, Eigen::Vector4d::Zero());
    std::vector<Eigen::Matrix4d> sq = std::vector<Eigen::Matrix4d>(24, Eigen::Matrix4d::Zero());
    std::vector<Eigen::Matrix4d> fit = std::vector<Eigen::Matrix4d>(24, Eigen::Matrix4d::Zero());
    int n = 0;
    double plug = 0.0;  // sum of plug-in V_p errors
    double term = 0.0;  // sum of the analysis's V_p terms
    void add(const CubeResult& r, double vp_true) {
        if (r.half_lines.size() != sum.size() || !std::isfinite(r.pit_volume_mm3)) return;
        for (const auto& h : r.half_lines) {
            if (!h.valid || !h.interior_cov.allFinite()) return;
        }
        ++n;
        const double p = r.rim.area_mm2 * r.rim_height_mm - r.rim_volume_mm3;
        plug += p - vp_true;
        term += p - r.pit_volume_mm3;
        for (std::size_t i = 0; i < sum.size(); ++i) {
            const Ctrl& q = r.half_lines[i].interior.control;
            const Eigen::Vector4d x(q[1].x() - q[0].x(), q[3].x() - q[2].x(), q[3].x(), q[3].y());
            sum[i] += x;
            sq[i] += x * x.transpose();
            fit[i] += r.half_lines[i].interior_cov;
        }
    }
    void print(const std::vector<Eigen::Matrix4d>& h_vp, const std::vector<Eigen::Matrix4d>& h_vir,
               double crb_vp, double crb_vir) const {
        if (n < 2) return;
        double t_fit = 0.0, t_emp = 0.0, t_vir = 0.0;
        Eigen::Vector4d ratio = Eigen::Vector4d::Zero();
        for (std::size_t i = 0; i < sum.size(); ++i) {
            const Eigen::Vector4d mu = sum[i] / n;
            const Eigen::Matrix4d emp = (sq[i] / n - mu * mu.transpose()) * n / (n - 1.0);
            const Eigen::Matrix4d f = fit[i] / n;
            t_fit += 0.5 * h_vp[i].cwiseProduct(f).sum();
            t_emp += 0.5 * h_vp[i].cwiseProduct(emp).sum();
            t_vir += 0.5 * h_vir[i].cwiseProduct(emp).sum();
            ratio += emp.diagonal().cwiseQuotient(f.diagonal()) / static_cast<double>(sum.size());
        }
        std::printf(
            "diagnose (%d eyes), in CRB: V_p plug-in bias %+.2f, the analysis's term %+.2f; the "
            "term with the fits' mean covariance %+.2f, with the realisations' covariance %+.2f; "
            "realisations' variance / fit covariance (mean over half-lines): alpha %.2f beta %.2f "
            "r_rim %.2f h_rim %.2f; V_IR's term (realisations' covariance) %+.3f\n",
            n, plug / n / crb_vp, term / n / crb_vp, t_fit / crb_vp, t_emp / crb_vp, ratio(0),
            ratio(1), ratio(2), ratio(3), t_vir / crb_vir);
    }
};


// kParams' values from the phantom's truth (MaculaTruth) or the analysis (CubeResult): the
// same field names in both.
template <class Parameters>
std::vector<double> parameter_values(const Parameters& t) {
    return {t.cft_mm,
            t.rim_height_mm,
            t.pit_depth_mm,
            t.rim.diameter_mm,
            t.rim.area_mm2,
            t.max_pit_slope_deg,
            t.slope.diameter_mm,
            t.slope.area_mm2,
            t.pit_flat_diameter_mm,
            t.pit_flat.area_mm2,
            t.rim_volume_mm3,
            t.inner_rim_volume_mm3,
            t.pit_volume_mm3,
            value(t.alpha_mean_mm),
            value(t.beta_mean_mm)};
}

MaculaPhantomParams phantom_params(int bscans) {
    MaculaPhantomParams p;  // as bench/macula_accuracy's volume(kBezier, bscans)
    p.family = MaculaFamily::kBezier;
    p.num_bscans = bscans;
    p.pixels = false;
    p.fovea_dx_mm = 0.0237;
    p.fovea_dy_mm = -0.0311;
    return p;
}

// The model of phantom p for the analysis settings topt (half-line directions in the grid).
Model model_of(const MaculaPhantomParams& p,
               const MaculaTruthOptions& topt,
               const phantom::VolumeLayout& layout) {
    Model m;
    m.n = topt.num_half_lines;
    m.radius_mm = topt.radius_mm;
    m.tau_mm = topt.tau_mm;
    m.inner_radius_mm = topt.inner_radius_mm;
    m.frame = phantom::grid_frame(layout);
    m.centre = macula_centre_mm(p);
    for (int i = 0; i < m.n; ++i) m.dir.push_back(m.frame.grid_direction(360.0 * i / m.n));
    return m;
}

// theta* from the phantom's truth (interior and exterior-to-R control points per half-line).
Eigen::VectorXd true_theta(const MaculaTruth& t, const Model& m) {
    std::vector<double> th(static_cast<std::size_t>(m.size()), 0.0);
    auto at = [&](int i, int k) -> double& { return th[static_cast<std::size_t>(m.line(i, k))]; };
    th[0] = t.cft_mm;
    for (int i = 0; i < m.n; ++i) {
        const HalfLineTruth& h = t.half_lines.at(static_cast<std::size_t>(i));
        const auto& in = h.interior_control_points;
        const auto& ex = h.exterior_to_r_control_points;
        at(i, kAlpha) = in.at(1)[0] - in.at(0)[0];
        at(i, kBeta) = in.at(3)[0] - in.at(2)[0];
        at(i, kRimR) = in.at(3)[0];
        at(i, kRimH) = in.at(3)[1];
        at(i, kAlphaExt) = ex.at(1)[0] - ex.at(0)[0];
        at(i, kP2x) = ex.at(2)[0];
        at(i, kP2y) = ex.at(2)[1];
        at(i, kP3y) = ex.at(3)[1];
    }
    return Eigen::Map<const Eigen::VectorXd>(th.data(), m.size());
}

struct Bound {
    Eigen::MatrixXd info;  // Fisher information, all unknowns (centre included)
    long nodes = 0;
    double mismatch_max_um = 0.0;  // |model - phantom| at theta*, over the nodes
    double mismatch_rms_um = 0.0;
    // sum over nodes of grad T (phantom - model) / sigma^2: J^-1 times this is the linearised
    // bias of a joint least-squares fit of the model to the noise-free phantom.
    Eigen::VectorXd score;
};

// Fisher information at th over the nodes within R. `score` is sum grad T e / sigma^2 with e the
// residual of the noise-free phantom (data == nullptr) or of a noisy thickness map, so that
// J^-1 score is a Gauss-Newton step of the least-squares fit.
Bound fisher(const Eigen::VectorXd& th,
             const Model& m,
             const MaculaPhantomParams& p,
             const phantom::VolumeLayout& layout,
             double h,
             const ThicknessMap* data = nullptr) {
    FisherAccumulator acc(m.size(), kSigmaUm * 1e-3);
    Bound b;
    double ss = 0.0;
    b.score = Eigen::VectorXd::Zero(m.size());
    const double inv_var = 1.0 / (kSigmaUm * 1e-3 * kSigmaUm * 1e-3);
    std::vector<int> idx(1 + 2 * kLineParams + 2);
    std::vector<double> d(idx.size());
    for (int row = 0; row < layout.num_bscans; ++row) {
        for (int a = 0; a < layout.size_x; ++a) {
            const V2 g(a * layout.scale_x_mm, row * layout.distance_mm);
            const V2 dv = g - m.centre;
            const double r = dv.norm();
            if (r >= m.radius_mm - 1e-4) continue;  // a centre step keeps the node within R
            const double s = m.frame.anatomical_angle_deg(dv.x(), dv.y()) * m.n / 360.0;
            const int i0 = static_cast<int>(std::floor(s)) % m.n;
            const double w = s - std::floor(s);
            const int i1 = (i0 + 1) % m.n;
            const double wt[2] = {1.0 - w, w};
            const int li[2] = {i0, i1};
            std::fill(d.begin(), d.end(), 0.0);
            idx[0] = 0;
            for (int side = 0; side < 2; ++side) {
                Line l = line_of(th, m, li[side]);
                {
                    Line u = l;
                    Line v = l;
                    u.cft += h;
                    v.cft -= h;
                    d[0] += wt[side] * (profile(u, m.radius_mm, r) - profile(v, m.radius_mm, r)) /
                            (2 * h);
                }
                for (int k = 0; k < kLineParams; ++k) {
                    Line u = l;
                    Line v = l;
                    u.q[static_cast<std::size_t>(k)] += h;
                    v.q[static_cast<std::size_t>(k)] -= h;
                    const std::size_t j = static_cast<std::size_t>(1 + side * kLineParams + k);
                    idx[j] = m.line(li[side], k);
                    d[j] = wt[side] * (profile(u, m.radius_mm, r) - profile(v, m.radius_mm, r)) /
                           (2 * h);
                }
            }
            for (int axis = 0; axis < 2; ++axis) {
                Eigen::VectorXd t = th;
                const int c = m.centre_index(axis);
                t(c) = th(c) + h;
                const double up = surface(t, m, g);
                t(c) = th(c) - h;
                const double down = surface(t, m, g);
                idx[idx.size() - 2 + static_cast<std::size_t>(axis)] = c;
                d[d.size() - 2 + static_cast<std::size_t>(axis)] = (up - down) / (2 * h);
            }
            acc.add(idx, d);
            const double e_mm =
                (data != nullptr
                     ? data->at(row, a)
                     : macula_thickness_mm(p, r, m.frame.anatomical_angle_deg(dv.x(), dv.y()))) -
                surface(th, m, g);
            for (std::size_t j = 0; j < idx.size(); ++j) b.score(idx[j]) += d[j] * e_mm * inv_var;
            const double e = 1e3 * e_mm;
            b.mismatch_max_um = std::max(b.mismatch_max_um, std::fabs(e));
            ss += e * e;
        }
    }
    b.info = acc.information();
    b.nodes = acc.observations();
    b.mismatch_rms_um = std::sqrt(ss / static_cast<double>(b.nodes));
    return b;
}

// The unknowns a joint fit keeps at their truth: the centre and every half-line's exterior
// alpha_ext, P2 (on a crest that falls ~0.1 mm over [rim, R] these are nearly unidentified:
// Gauss-Newton steps of several mm there leave the linear regime, so the fit checks the bound
// of the model without them, and the bench prints that bound beside it).
std::vector<int> fit_known(const Model& m) {
    std::vector<int> k{m.centre_index(0), m.centre_index(1)};
    for (int i = 0; i < m.n; ++i) {
        for (const int q : {kAlphaExt, kP2x, kP2y}) k.push_back(m.line(i, q));
    }
    std::sort(k.begin(), k.end());
    return k;
}

// CRB SDs of every derived parameter (centre known and centre estimated) and of CFT variants.
struct Crb {
    std::vector<double> sd_known;  // centre known
    std::vector<double> sd_free;   // centre estimated
    double cft_ab_known = 0.0;     // CFT with every alpha_i, beta_i known (centre known)
    double cft_all_known = 0.0;    // CFT with every other unknown known
    // Smoother models (centre known): alpha_i, beta_i (and r_rim,i, h_rim,i) not free per
    // half-line but a Fourier series of order 2 in the half-line angle (5 coefficients each),
    // which the phantom's truth satisfies exactly (bezier_profile).
    std::vector<double> sd_fourier_ab;
    std::vector<double> sd_fourier_abwh;
    std::vector<double> sd_cft_known;   // CFT known (centre known): what an oracle CFT leaves
    std::vector<double> mismatch_bias;  // linearised bias from the angular interpolation
    std::vector<double> sd_fit_model;   // the unknowns of fit_known known (the joint fit's model)
};

// theta = A phi: the per-line parameters in `smooth` replaced by Fourier coefficients of order
// 2 in the anatomical half-line angle; every other unknown is its own column. Centre columns
// are returned in `centre_cols`.
Eigen::MatrixXd fourier_map(const Model& m,
                            const std::vector<int>& smooth,
                            std::vector<int>& centre_cols) {
    const int nf = 5;
    std::vector<std::vector<std::pair<int, double>>> rows(static_cast<std::size_t>(m.size()));
    int col = 0;
    rows[0].push_back({col++, 1.0});
    for (const int k : smooth) {
        for (int i = 0; i < m.n; ++i) {
            const double a = 2.0 * kPi * i / m.n;
            const double f[nf] = {1.0, std::cos(a), std::sin(a), std::cos(2 * a), std::sin(2 * a)};
            for (int j = 0; j < nf; ++j) {
                rows[static_cast<std::size_t>(m.line(i, k))].push_back({col + j, f[j]});
            }
        }
        col += nf;
    }
    for (int i = 0; i < m.n; ++i) {
        for (int k = 0; k < kLineParams; ++k) {
            if (std::find(smooth.begin(), smooth.end(), k) != smooth.end()) continue;
            rows[static_cast<std::size_t>(m.line(i, k))].push_back({col++, 1.0});
        }
    }
    centre_cols.clear();
    for (int axis = 0; axis < 2; ++axis) {
        centre_cols.push_back(col);
        rows[static_cast<std::size_t>(m.centre_index(axis))].push_back({col++, 1.0});
    }
    Eigen::MatrixXd a = Eigen::MatrixXd::Zero(m.size(), col);
    for (std::size_t r = 0; r < rows.size(); ++r) {
        for (const auto& [c, v] : rows[r]) a(static_cast<Eigen::Index>(r), c) = v;
    }
    return a;
}

Crb crb(const Bound& b, const Eigen::VectorXd& th, const Model& m, double h) {
    const std::vector<int> centre{m.centre_index(0), m.centre_index(1)};
    const Eigen::MatrixXd cov_free = crb_covariance(b.info);
    const Eigen::MatrixXd cov_known = crb_covariance(without(b.info, centre));
    const Eigen::VectorXd steps = Eigen::VectorXd::Constant(th.size(), h);
    std::vector<int> cc_ab;
    std::vector<int> cc_abwh;
    const Eigen::MatrixXd a_ab = fourier_map(m, {kAlpha, kBeta}, cc_ab);
    const Eigen::MatrixXd a_abwh = fourier_map(m, {kAlpha, kBeta, kRimR, kRimH}, cc_abwh);
    const Eigen::MatrixXd cov_ab =
        crb_covariance(without(Eigen::MatrixXd(a_ab.transpose() * b.info * a_ab), cc_ab));
    const Eigen::MatrixXd cov_abwh =
        crb_covariance(without(Eigen::MatrixXd(a_abwh.transpose() * b.info * a_abwh), cc_abwh));
    const std::vector<int> centre_cft{0, m.centre_index(0), m.centre_index(1)};
    const Eigen::MatrixXd cov_cft = crb_covariance(without(b.info, centre_cft));
    const Eigen::VectorXd bias_theta = cov_free * b.score;
    const Eigen::MatrixXd cov_fit = crb_covariance(without(b.info, fit_known(m)));
    Crb c;
    for (std::size_t k = 0; k < kParams.size(); ++k) {
        const Eigen::VectorXd grad =
            central_gradient([&](const Eigen::VectorXd& t) { return derived(t, m)[k]; }, th, steps);
        c.sd_free.push_back(std::sqrt(crb_variance(cov_free, grad)));
        c.sd_known.push_back(std::sqrt(crb_variance(cov_known, without(grad, centre))));
        const Eigen::VectorXd g_ab = a_ab.transpose() * grad;
        const Eigen::VectorXd g_abwh = a_abwh.transpose() * grad;
        c.sd_fourier_ab.push_back(std::sqrt(crb_variance(cov_ab, without(g_ab, cc_ab))));
        c.sd_fourier_abwh.push_back(std::sqrt(crb_variance(cov_abwh, without(g_abwh, cc_abwh))));
        c.sd_cft_known.push_back(std::sqrt(crb_variance(cov_cft, without(grad, centre_cft))));
        c.mismatch_bias.push_back(grad.dot(bias_theta));
        c.sd_fit_model.push_back(std::sqrt(crb_variance(cov_fit, without(grad, fit_known(m)))));
    }
    std::vector<int> ab = centre;
    for (int i = 0; i < m.n; ++i) {
        ab.push_back(m.line(i, kAlpha));
        ab.push_back(m.line(i, kBeta));
    }
    c.cft_ab_known = std::sqrt(crb_covariance(without(b.info, ab))(0, 0));
    c.cft_all_known = 1.0 / std::sqrt(b.info(0, 0));
    return c;
}

// Residual sum of squares (mm^2) of the model at th against the map's nodes within R.
double residual_ss(const Eigen::VectorXd& th,
                   const Model& m,
                   const phantom::VolumeLayout& layout,
                   const ThicknessMap& map) {
    double ss = 0.0;
    for (int row = 0; row < layout.num_bscans; ++row) {
        for (int a = 0; a < layout.size_x; ++a) {
            const V2 g(a * layout.scale_x_mm, row * layout.distance_mm);
            if ((g - m.centre).norm() >= m.radius_mm - 1e-4) continue;
            const double e = map.at(row, a) - surface(th, m, g);
            ss += e * e;
        }
    }
    return ss;
}

// The graph constraints of cube.cpp's fits on every half-line (both curves x-monotone).
bool feasible(const Eigen::VectorXd& th, const Model& m) {
    for (int i = 0; i < m.n; ++i) {
        const Line l = line_of(th, m, i);
        const auto& q = l.q;
        if (q[kAlpha] < 0.0 || q[kBeta] < 0.0 || q[kAlpha] + q[kBeta] > q[kRimR]) return false;
        if (q[kAlphaExt] < 0.0 || q[kRimR] + q[kAlphaExt] > q[kP2x] || q[kP2x] > m.radius_mm) {
            return false;
        }
    }
    return true;
}

// A joint least-squares fit of the model to every noisy node within R, the unknowns of
// fit_known at their truth: Gauss-Newton from theta*, a step halved (to 1/64) until it keeps the
// graph constraints and lowers the sum of squares; stops when the step's predicted decrease of
// chi^2 (score^T J^-1 score) is below 1e-6, or after 20 steps. `steps`: steps taken.
Eigen::VectorXd joint_fit(const Eigen::VectorXd& th0,
                          const Model& m,
                          const MaculaPhantomParams& p,
                          const phantom::VolumeLayout& layout,
                          const ThicknessMap& map,
                          double h,
                          int& steps) {
    const std::vector<int> known = fit_known(m);
    std::vector<int> free;
    for (int k = 0; k < m.size(); ++k) {
        if (!std::binary_search(known.begin(), known.end(), k)) free.push_back(k);
    }
    Eigen::VectorXd th = th0;
    double ss = residual_ss(th, m, layout, map);
    for (steps = 0; steps < 20; ++steps) {
        const Bound b = fisher(th, m, p, layout, h, &map);
        const Eigen::VectorXd score = without(b.score, known);
        const Eigen::VectorXd step = crb_covariance(without(b.info, known)) * score;
        if (step.dot(score) < 1e-6) break;
        bool moved = false;
        for (double lambda = 1.0; lambda >= 1.0 / 64 && !moved; lambda /= 2) {
            Eigen::VectorXd cand = th;
            for (std::size_t j = 0; j < free.size(); ++j) {
                cand(free[j]) += lambda * step(static_cast<Eigen::Index>(j));
            }
            if (!feasible(cand, m)) continue;
            const double cs = residual_ss(cand, m, layout, map);
            if (cs < ss) {
                th = cand;
                ss = cs;
                moved = true;
            }
        }
        if (!moved) break;
    }
    return th;
}

// `centre`: the centre's offset on the noise-free phantoms against the half-side of the window
// whose quadratic vertex places it (under noise it widens as sigma^(1/3): 0.178 / 0.224 / 0.283
// mm at 0.5 / 1 / 2 px per surface), on 61, 97 and 193 B-scans: a deterministic
// offset that grows with the window on every grid is the pit's own asymmetry, not the noise
// and not the B-scans' spacing (docs/algorithms/cube.md, session 45).
int centre_table() {
    std::printf("centre error (um, grid x / y) of the noise-free Bezier phantom against the "
                "centre window's half-side R\n%-8s", "R (mm)");
    const std::vector<double> radii{0.06, 0.1, 0.15, 0.178, 0.224, 0.283, 0.35};
    for (const double r : radii) std::printf(" %15.3f", r);
    std::printf("\n");
    for (const int nb : {61, 97, 193}) {
        const MaculaPhantomParams p = phantom_params(nb);
        const MaculaTruthOptions topt;
        const MaculaPhantom ph = make_macula_phantom(p, topt);
        std::printf("%3d B-sc", nb);
        for (const double r : radii) {
            CubeParams cp;
            cp.centre_fit_radius_mm = r;
            const CubeResult res = analyse_macula(ph.scan, cp);
            const V2 e = 1e3 * (res.centre_mm - ph.centre_mm);
            std::printf("   %+5.1f / %+5.1f", e.x(), e.y());
        }
        std::printf("\n");
    }
    return 0;
}

// `macula_crb bias [REALISATIONS]`: the bias and RMS of every parameter of analyse_macula on
// the 61-B-scan Bezier phantom against its CRB (centre estimated, as the analysis estimates
// it), at 0.5, 1 and 2 axial pixels of segmentation noise on ILM and on BM each (node SD
// sqrt(2) x that). The CRB scales linearly with the node SD. Seeds 1001, 1002, ... at every
// noise level (common random numbers). The bias's standard error is SD / sqrt(REALISATIONS):
// <= 0.1 CRB needs REALISATIONS >= 100 (SD / CRB)^2, i.e. ~300 for SD up to 1.7 CRB.
int bias_table(int realisations, std::vector<double> levels, int nb, bool true_centre,
               bool diagnose) {
    const MaculaPhantomParams p = phantom_params(nb);
    const MaculaTruthOptions topt;
    const MaculaTruth truth = macula_truth(p, topt);
    const phantom::VolumeLayout layout = macula_layout(p);
    const Model m = model_of(p, topt, layout);
    const Eigen::VectorXd th = true_theta(truth, m);
    const std::vector<double> tv = parameter_values(truth);
    const double h = 1e-6;
    const Crb c = crb(fisher(th, m, p, layout, h), th, m, h);
    std::vector<Eigen::Matrix4d> h_vp;
    std::vector<Eigen::Matrix4d> h_vir;
    if (diagnose) {
        h_vp = line_hessians(th, m, 12);
        h_vir = line_hessians(th, m, 11);
    }
    std::printf(
        "CuBe bias and RMS against the CRB (centre estimated): Bezier phantom, %d B-scans, %d "
        "realisations per noise level (seeds 1001...), noise per surface (ILM and BM each)%s\n",
        nb, realisations, true_centre ? "; ORACLE: the analysis given the true centre" : "");
    {
        // Noise-free: what the sampling alone leaves, with the noise-adaptive samples (the path
        // every noisy eye takes) forced on, and with the bilinear samples (the default here).
        const MaculaPhantom ph = make_macula_phantom(p, topt);
        CubeParams forced;
        forced.local_fit_min_noise_um = 0.0;
        const std::vector<double> rf = parameter_values(analyse_macula(ph.scan, forced));
        const std::vector<double> rb = parameter_values(analyse_macula(ph.scan));
        std::printf("\nnoise-free, error in units of the 1 px CRB (and in %%): %-6s %9s %9s %9s %9s\n",
                    "", "adaptive", "bilinear", "adapt. %", "bilin. %");
        for (std::size_t k = 0; k < kParams.size(); ++k) {
            const double crb_sd = c.sd_free[k] * std::sqrt(2.0) * 3.8717 / kSigmaUm;
            const double t = std::fabs(tv[k]);
            std::printf("  %-17s %+9.2f %+9.2f %+9.3f %+9.3f\n", kParams[k].name,
                        (rf[k] - tv[k]) / crb_sd, (rb[k] - tv[k]) / crb_sd,
                        100.0 * (rf[k] - tv[k]) / t, 100.0 * (rb[k] - tv[k]) / t);
        }
    }
    if (levels.empty()) levels = {0.5, 1.0, 2.0};
    for (const double px : levels) {
        const double surface_um = px * 3.8717;
        const double node_um = std::sqrt(2.0) * surface_um;
        std::vector<std::vector<double>> err(kParams.size());
        double cpu_s = 0.0;
        double cx = 0.0, cy = 0.0;
        NoiseTermProbe probe;
        for (int s = 0; s < realisations; ++s) {
            MaculaPhantomParams q = p;
            q.noise_um = surface_um;
            q.seed = static_cast<std::uint64_t>(1001 + s);
            const MaculaPhantom ph = make_macula_phantom(q, topt);
            const auto t0 = std::chrono::steady_clock::now();
            CubeParams cp;
            if (true_centre) cp.centre_mm = ph.centre_mm;
            const CubeResult r = analyse_macula(ph.scan, cp);
            cpu_s += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
            if (diagnose) probe.add(r, tv[12]);
            const std::vector<double> rv = parameter_values(r);
            cx += (r.centre_mm - ph.centre_mm).x() / realisations;
            cy += (r.centre_mm - ph.centre_mm).y() / realisations;
            // A disk or volume is omitted (NaN) when a half-line fails: counted, not averaged.
            for (std::size_t k = 0; k < kParams.size(); ++k) {
                if (std::isfinite(rv[k])) err[k].push_back(rv[k] - tv[k]);
            }
        }
        std::printf(
            "\n%.1f px per surface (%.2f um; node SD %.2f um), analysis %.1f ms per eye\n"
            "%-17s %-4s %11s %10s %8s | %9s %9s %8s %8s %9s %9s %7s\n",
            px, surface_um, node_um, 1e3 * cpu_s / realisations, "parameter", "unit", "truth",
            "CRB", "CRB %", "bias %", "RMS %", "bias/CRB", "SE/CRB", "RMS/CRB", "|b|<=0.3?",
            "omitted");
        // The centre's mean error (estimated minus true, grid x and y): a deterministic offset
        // moves every parameter measured about it (V_IR most: docs/algorithms/cube.md).
        std::printf("mean centre error %+.2f %+.2f um (grid x, y)\n", 1e3 * cx, 1e3 * cy);
        if (diagnose) {
            probe.print(h_vp, h_vir, c.sd_free[12] * node_um / kSigmaUm,
                        c.sd_free[11] * node_um / kSigmaUm);
        }
        for (std::size_t k = 0; k < kParams.size(); ++k) {
            const double crb_sd = c.sd_free[k] * node_um / kSigmaUm;
            double sum = 0.0;
            double sq = 0.0;
            for (const double e : err[k]) {
                sum += e;
                sq += e * e;
            }
            const double n = static_cast<double>(err[k].size());
            const double mean = sum / n;
            const double rms = std::sqrt(sq / n);
            const double sd = std::sqrt(std::max(0.0, sq / n - mean * mean) * n / (n - 1.0));
            const double t = std::fabs(tv[k]);
            std::printf("%-17s %-4s %11.5g %10.4g %8.3f | %+9.3f %9.3f %+8.2f %8.2f %9.2f %9s %7zu\n",
                        kParams[k].name, kParams[k].unit, tv[k] * kParams[k].scale,
                        crb_sd * kParams[k].scale, 100.0 * crb_sd / t, 100.0 * mean / t,
                        100.0 * rms / t, mean / crb_sd, sd / std::sqrt(n) / crb_sd, rms / crb_sd,
                        std::fabs(mean) <= 0.3 * crb_sd ? "yes" : "NO",
                        static_cast<std::size_t>(realisations) - err[k].size());
        }
    }
    return 0;
}

}  // namespace

// Long (160 lines, over the 150 of the style) on purpose: the benchmark's modes, each a protocol
// read top to bottom against the table it prints; it ships no result.
int main(int argc, char** argv) {
    if (argc > 1 && std::string(argv[1]) == "bias") {
        // Further arguments: other noise levels (px per surface), e.g. 0.1 to see the part of
        // a bias that does not shrink with the noise.
        // "--bscans=N": another phantom than the 61-B-scan one (e.g. 193).
        // "--true-centre": the analysis given the phantom's centre (an oracle: what the
        // centre's own error costs). "--diagnose": the plug-in volumes' noise terms
        // (NoiseTermProbe).
        std::vector<double> levels;
        int nb = 61;
        int realisations = 300;
        bool true_centre = false;
        bool diagnose = false;
        for (int a = 2; a < argc; ++a) {
            const std::string arg = argv[a];
            if (arg.rfind("--bscans=", 0) == 0) {
                nb = std::max(3, std::atoi(arg.c_str() + 9));
            } else if (arg == "--true-centre") {
                true_centre = true;
            } else if (arg == "--diagnose") {
                diagnose = true;
            } else if (a == 2) {
                realisations = std::max(2, std::atoi(argv[a]));
            } else {
                levels.push_back(std::atof(argv[a]));
            }
        }
        return bias_table(realisations, levels, nb, true_centre, diagnose);
    }
    if (argc > 1 && std::string(argv[1]) == "centre") return centre_table();
    const int seeds = argc > 1 ? std::max(0, std::atoi(argv[1])) : 36;
    const int fit_seeds = argc > 2 ? std::max(0, std::atoi(argv[2])) : 0;
    std::printf(
        "CuBe Cramer-Rao bound: Bezier phantom, thickness node noise SD %.4f um "
        "(independent), model = %d half-line CuBe profiles linear in angle, R = 2 mm\n",
        kSigmaUm, 24);
    for (const int nb : {61, 97, 193}) {
        const auto t0 = std::chrono::steady_clock::now();
        const MaculaPhantomParams p = phantom_params(nb);
        const MaculaTruthOptions topt;
        const MaculaTruth truth = macula_truth(p, topt);
        const phantom::VolumeLayout layout = macula_layout(p);
        const Model m = model_of(p, topt, layout);
        const Eigen::VectorXd th = true_theta(truth, m);
        const std::vector<double> tv = parameter_values(truth);

        // Check 1: the restated formulas at theta* against the phantom's own truth.
        const std::vector<double> g0 = derived(th, m);
        double dev_truth = 0.0;
        for (std::size_t k = 0; k < tv.size(); ++k) {
            dev_truth = std::max(dev_truth, std::fabs(g0[k] / tv[k] - 1.0));
        }
        const double h = 1e-6;  // mm: rounding ~1e-16 / h, truncation ~h^2 T''' (see cube.md)
        const Bound b = fisher(th, m, p, layout, h);
        const Crb c = crb(b, th, m, h);
        const Bound b2 = fisher(th, m, p, layout, h / 2);
        const Crb c2 = crb(b2, th, m, h / 2);
        double dev_step = 0.0;
        for (std::size_t k = 0; k < kParams.size(); ++k) {
            dev_step = std::max(dev_step, std::fabs(c2.sd_free[k] / c.sd_free[k] - 1.0));
            dev_step = std::max(dev_step, std::fabs(c2.sd_known[k] / c.sd_known[k] - 1.0));
        }
        const double bound_s =
            std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();

        // The analysis on noisy seeds; check 2: the restated formulas on its fitted curves.
        std::vector<double> sum(kParams.size(), 0.0);
        std::vector<double> sum_sq(kParams.size(), 0.0);  // relative errors
        std::vector<double> mse(kParams.size(), 0.0);     // absolute
        double dev_result = 0.0;
        const auto t1 = std::chrono::steady_clock::now();
        for (int s = 0; s < seeds; ++s) {
            MaculaPhantomParams q = p;
            q.noise_um = kSigmaUm / std::sqrt(2.0);  // on ILM and BM each
            q.seed = static_cast<std::uint64_t>(7 + s);
            const MaculaPhantom ph = make_macula_phantom(q, topt);
            const CubeResult r = analyse_macula(ph.scan);
            const std::vector<double> rv = parameter_values(r);
            std::vector<Ctrl> in;
            for (const auto& hl : r.half_lines) in.push_back(hl.interior.control);
            const std::vector<double> rg = derived(in, m);
            for (std::size_t k = 0; k < kParams.size(); ++k) {
                dev_result = std::max(dev_result, std::fabs(rg[k] / rv[k] - 1.0));
                const double rel = rv[k] / tv[k] - 1.0;
                sum[k] += rel;
                sum_sq[k] += rel * rel;
                mse[k] += (rv[k] - tv[k]) * (rv[k] - tv[k]);
            }
        }
        const double seeds_s =
            std::chrono::duration<double>(std::chrono::steady_clock::now() - t1).count();

        std::printf(
            "\n%d B-scans: %ld nodes within R, %d unknowns (CFT, 8 x %d per half-line, "
            "centre); model vs phantom at theta*: max %.3f um, RMS %.3f um\n",
            nb, b.nodes, m.size(), m.n, b.mismatch_max_um, b.mismatch_rms_um);
        std::printf(
            "checks: formulas at theta* vs phantom truth max rel dev %.1e; vs the "
            "analysis's outputs on its own fits %.1e; CRB step h -> h/2 max rel change "
            "%.1e\n",
            dev_truth, seeds > 0 ? dev_result : 0.0, dev_step);
        std::printf("%-17s %-4s %11s %10s %8s %8s %8s %8s %8s %8s | %8s %8s %8s %6s\n", "parameter",
                    "unit", "truth", "CRB SD", "CRB %", "2CRB %", "CRBc %", "F_ab %", "CFTk %",
                    "bias %", "RMS %", "mean %", "RMS/CRBc", "eff");
        for (std::size_t k = 0; k < kParams.size(); ++k) {
            const Param& q = kParams[k];
            const double pct_known = 100.0 * c.sd_known[k] / std::fabs(tv[k]);
            const double pct_free = 100.0 * c.sd_free[k] / std::fabs(tv[k]);
            std::printf("%-17s %-4s %11.5g %10.4g %8.3f %8.3f %8.3f %8.3f %8.3f %8.3f |", q.name,
                        q.unit, tv[k] * q.scale, c.sd_known[k] * q.scale, pct_known,
                        2.0 * pct_known, pct_free, 100.0 * c.sd_fourier_ab[k] / std::fabs(tv[k]),
                        100.0 * c.sd_cft_known[k] / std::fabs(tv[k]),
                        100.0 * c.mismatch_bias[k] / std::fabs(tv[k]));
            if (seeds > 0) {
                const double rms = 100.0 * std::sqrt(sum_sq[k] / seeds);
                const double eff = c.sd_free[k] * c.sd_free[k] / (mse[k] / seeds);
                std::printf(" %8.3f %8.3f %8.2f %6.3f\n", rms, 100.0 * sum[k] / seeds,
                            rms / pct_free, eff);
            } else {
                std::printf("\n");
            }
        }
        double fourier_dev = 0.0;
        for (std::size_t k = 0; k < kParams.size(); ++k) {
            fourier_dev =
                std::max(fourier_dev, std::fabs(c.sd_fourier_abwh[k] / c.sd_fourier_ab[k] - 1.0));
        }
        std::printf(
            "r_rim,i and h_rim,i an order-2 Fourier series too: every CRB within %.1f %% "
            "of F_ab\n",
            100.0 * fourier_dev);
        std::printf(
            "CFT CRB SD (um): all unknowns %.4f (centre known) / %.4f (estimated); "
            "alpha_i, beta_i known %.4f; everything else known %.4f\n",
            1e3 * c.sd_known[0], 1e3 * c.sd_free[0], 1e3 * c.cft_ab_known, 1e3 * c.cft_all_known);
        std::printf("time: bound %.1f s (two step sizes), %d noisy analyses %.1f s\n", bound_s,
                    seeds, seeds_s);
        if (fit_seeds > 0) {
            // Is the bound attained? The joint fit on the same seeds' nodes.
            const auto t2 = std::chrono::steady_clock::now();
            std::vector<double> fsum(kParams.size(), 0.0);
            std::vector<double> fsq(kParams.size(), 0.0);
            int max_steps = 0;
            for (int s = 0; s < fit_seeds; ++s) {
                MaculaPhantomParams q = p;
                q.noise_um = kSigmaUm / std::sqrt(2.0);
                q.seed = static_cast<std::uint64_t>(7 + s);
                const MaculaPhantom ph = make_macula_phantom(q, topt);
                int steps = 0;
                const Eigen::VectorXd fit =
                    joint_fit(th, m, p, layout, thickness_map(ph.scan), h, steps);
                max_steps = std::max(max_steps, steps);
                const std::vector<double> fv = derived(fit, m);
                for (std::size_t k = 0; k < kParams.size(); ++k) {
                    const double rel = fv[k] / tv[k] - 1.0;
                    fsum[k] += rel;
                    fsq[k] += rel * rel;
                }
            }
            std::printf(
                "joint least-squares fit, centre and exterior alpha_ext, P2 known, %d "
                "seeds (<= %d steps, %.1f s): RMS %% (mean %%) / its model's CRB %% / "
                "CRB %%\n",
                fit_seeds, max_steps,
                std::chrono::duration<double>(std::chrono::steady_clock::now() - t2).count());
            for (std::size_t k = 0; k < kParams.size(); ++k) {
                const double rms = 100.0 * std::sqrt(fsq[k] / fit_seeds);
                std::printf("  %-17s %7.3f (%+7.3f) / %6.3f / %6.3f\n", kParams[k].name, rms,
                            100.0 * fsum[k] / fit_seeds,
                            100.0 * c.sd_fit_model[k] / std::fabs(tv[k]),
                            100.0 * c.sd_known[k] / std::fabs(tv[k]));
            }
        }
    }
    std::printf(
        "\nCRB %%: SD bound / truth, centre known; CRBc %%: centre estimated too; "
        "F_ab %%: alpha_i, beta_i an order-2 Fourier series in the angle (centre "
        "known); CFTk %%: CFT known (centre known); bias %%: linearised bias of a joint "
        "fit to the noise-free phantom (model mismatch between half-lines); RMS/mean "
        "%%: the analysis over the seeds (relative error); eff = CRBc^2 / MSE.\n");
    return 0;
}
