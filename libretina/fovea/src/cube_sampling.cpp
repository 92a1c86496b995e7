// CuBe fovea analysis, the samples (thesis §7.2.1, docs/algorithms/cube.md steps 1-3): the
// thickness map, its noise, the fovea centre and the radial half-lines, with the noise-adaptive
// estimators (local fits, sector bins). Decisions: docs/algorithms/cube.md.

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <string>

#include "cube_stages.h"
#include "octshape/error.h"
#include "octshape/retina/cube.h"
#include "octshape/retina/scan_geometry.h"

namespace octshape::retina {
using namespace cube_detail;
namespace {

// The thickness map smoothed by a separable Gaussian of SD `sigma` mm (normalised over the
// valid nodes) on the node box rows [b0, b1] x columns [a0, a1], row-major; NaN where the node
// itself is missing. Used to locate the centre only.
struct NodeBox {
    int b0 = 0, b1 = 0, a0 = 0, a1 = 0;
    [[nodiscard]] int cols() const { return a1 - a0 + 1; }
};
std::vector<double> smoothed_box(const ThicknessMap& m, const NodeBox& bx, double sigma) {
    auto kernel = [&](double step) {
        std::vector<double> k{1.0};
        if (!(step > 0.0) || !(sigma > 0.0)) return k;
        const int half = static_cast<int>(std::ceil(3.0 * sigma / step));
        k.assign(static_cast<std::size_t>(2 * half + 1), 0.0);
        for (int i = -half; i <= half; ++i) {
            const double u = i * step / sigma;
            k[static_cast<std::size_t>(i + half)] = std::exp(-0.5 * u * u);
        }
        return k;
    };
    const std::vector<double> kx = kernel(m.dx_mm);
    const std::vector<double> ky = kernel(m.rows > 1 ? m.dy_mm : 0.0);
    const int hx = static_cast<int>(kx.size() / 2);
    const int hy = static_cast<int>(ky.size() / 2);
    const int r0 = std::max(0, bx.b0 - hy);
    const int r1 = std::min(m.rows - 1, bx.b1 + hy);
    const int nc = bx.cols();
    // Horizontal pass: weighted sums and weights of the valid nodes.
    std::vector<double> num(static_cast<std::size_t>((r1 - r0 + 1) * nc), 0.0);
    std::vector<double> den(num.size(), 0.0);
    for (int b = r0; b <= r1; ++b) {
        for (int a = bx.a0; a <= bx.a1; ++a) {
            double sn = 0.0;
            double sd = 0.0;
            for (int i = -hx; i <= hx; ++i) {
                const int aa = a + i;
                if (aa < 0 || aa >= m.cols) continue;
                const double v = m.at(b, aa);
                if (std::isnan(v)) continue;
                const double w = kx[static_cast<std::size_t>(i + hx)];
                sn += w * v;
                sd += w;
            }
            const auto j = static_cast<std::size_t>((b - r0) * nc + (a - bx.a0));
            num[j] = sn;
            den[j] = sd;
        }
    }
    std::vector<double> out(static_cast<std::size_t>((bx.b1 - bx.b0 + 1) * nc), kMissing);
    for (int b = bx.b0; b <= bx.b1; ++b) {
        for (int a = bx.a0; a <= bx.a1; ++a) {
            if (std::isnan(m.at(b, a))) continue;
            double sn = 0.0;
            double sd = 0.0;
            for (int i = -hy; i <= hy; ++i) {
                const int bb = b + i;
                if (bb < r0 || bb > r1) continue;
                const auto j = static_cast<std::size_t>((bb - r0) * nc + (a - bx.a0));
                const double w = ky[static_cast<std::size_t>(i + hy)];
                sn += w * num[j];
                sd += w * den[j];
            }
            out[static_cast<std::size_t>((b - bx.b0) * nc + (a - bx.a0))] = sn / sd;
        }
    }
    return out;
}

using Quadratic = Eigen::Matrix<double, 6, 1>;

// The normal equations of the least-squares quadratic k0 + k1 u + k2 w + k3 u^2 + k4 u w +
// k5 w^2, (u, w) = p - c, over the valid nodes p of M with |u| <= rx, |w| <= ry (w = 0 for a
// line scan); returns the node count.
int quadratic_normal_equations(const ThicknessMap& m,
                               const V2& c,
                               double rx,
                               double ry,
                               Eigen::Matrix<double, 6, 6>& N,
                               Quadratic& rhs) {
    const bool line = m.rows == 1;
    const int a0 = std::max(0, static_cast<int>(std::floor((c.x() - rx) / m.dx_mm)));
    const int a1 = std::min(m.cols - 1, static_cast<int>(std::ceil((c.x() + rx) / m.dx_mm)));
    int b0 = 0;
    int b1 = 0;
    if (!line) {
        b0 = std::max(0, static_cast<int>(std::floor((c.y() - ry) / m.dy_mm)));
        b1 = std::min(m.rows - 1, static_cast<int>(std::ceil((c.y() + ry) / m.dy_mm)));
    }
    N.setZero();
    rhs.setZero();
    int count = 0;
    for (int b = b0; b <= b1; ++b) {
        for (int a = a0; a <= a1; ++a) {
            const double v = m.at(b, a);
            if (std::isnan(v)) continue;
            const double u = a * m.dx_mm - c.x();
            const double w = line ? 0.0 : b * m.dy_mm - c.y();
            if (std::fabs(u) > rx + 1e-12 || std::fabs(w) > ry + 1e-12) continue;
            Quadratic phi;
            phi << 1.0, u, w, u * u, u * w, w * w;
            N += phi * phi.transpose();
            rhs += phi * v;
            ++count;
        }
    }
    return count;
}

// The pit floor under noise (docs/algorithms/cube.md "Radial samples under noise"): the
// quadratic surface over the window |u| <= rx, |w| <= ry around c (2-D maps only); nullopt when
// the design is singular (fewer than 3 B-scans or A-scans in the window, missing nodes).
std::optional<Quadratic> quadratic_surface(const ThicknessMap& m, const V2& c, double rx,
                                           double ry) {
    Eigen::Matrix<double, 6, 6> N;
    Quadratic rhs;
    if (m.rows == 1 || quadratic_normal_equations(m, c, rx, ry, N, rhs) < 12) return std::nullopt;
    // In window units (u / rx, w / ry: unknowns k_j rx^i ry^j) so that the pivots compare.
    Quadratic s;
    s << 1.0, 1.0 / rx, 1.0 / ry, 1.0 / (rx * rx), 1.0 / (rx * ry), 1.0 / (ry * ry);
    const Eigen::Matrix<double, 6, 6> Ns = s.asDiagonal() * N * s.asDiagonal();
    const Eigen::LDLT<Eigen::Matrix<double, 6, 6>> ldlt(Ns);
    const auto d = ldlt.vectorD();
    if (ldlt.info() != Eigen::Success || !(d.minCoeff() > 1e-9 * d.maxCoeff())) {
        return std::nullopt;
    }
    const Quadratic k = s.asDiagonal() * ldlt.solve(s.asDiagonal() * rhs);
    return k.allFinite() ? std::optional<Quadratic>(k) : std::nullopt;
}

// Vertex of the least-squares quadratic surface fitted to the valid nodes of M within the window
// |x - c.x| <= rx, |y - c.y| <= ry (a parabola in x for a line scan); nullopt when the fit is not
// a bowl or its vertex leaves the window. `value`, when given, receives the surface's height at
// the vertex (2-D fits only; the analysis's centre sample under noise when the half-window fit
// fails).
std::optional<V2> quadratic_vertex(
    const ThicknessMap& m, const V2& c, double rx, double ry, double* value = nullptr) {
    const bool line = m.rows == 1;
    Eigen::Matrix<double, 6, 6> N;
    Quadratic rhs;
    const int count = quadratic_normal_equations(m, c, rx, ry, N, rhs);
    if (line) {
        // 1-D: unknowns (1, u, u^2).
        const std::array<int, 3> id{0, 1, 3};
        Eigen::Matrix3d N3;
        Eigen::Vector3d r3;
        for (int i = 0; i < 3; ++i) {
            r3(i) = rhs(id[static_cast<std::size_t>(i)]);
            for (int j = 0; j < 3; ++j) {
                N3(i, j) = N(id[static_cast<std::size_t>(i)], id[static_cast<std::size_t>(j)]);
            }
        }
        if (count < 5) return std::nullopt;
        const Eigen::Vector3d k = N3.ldlt().solve(r3);
        if (!(k(2) > 0.0)) return std::nullopt;
        const double u = -k(1) / (2.0 * k(2));
        if (!std::isfinite(u) || std::fabs(u) > rx) return std::nullopt;
        return V2(c.x() + u, c.y());
    }
    if (count < 12) return std::nullopt;
    const Eigen::Matrix<double, 6, 1> k = N.ldlt().solve(rhs);
    Eigen::Matrix2d Hs;
    Hs << 2.0 * k(3), k(4), k(4), 2.0 * k(5);
    if (!k.allFinite() || !(Hs(0, 0) > 0.0) || !(Hs.determinant() > 0.0)) return std::nullopt;
    const V2 v = -Hs.inverse() * V2(k(1), k(2));
    if (std::fabs(v.x()) > rx || std::fabs(v.y()) > ry) return std::nullopt;
    // At the vertex the gradient k1 + Hs v vanishes: k0 + k.v + v^T Hs v / 2 = k0 + k.v / 2.
    if (value != nullptr) *value = k(0) + 0.5 * (k(1) * v.x() + k(2) * v.y());
    return c + v;
}

// Windows of the noise-adaptive estimators (docs/algorithms/cube.md "Radial samples under
// noise", measured on 36 noisy seeds at 193 B-scans and the 61-B-scan re-scans): a radial
// sample's window spans +-4 sample steps in radius (the quadratic's intercept then has the
// noise of a mean over ~+-2 steps) and at least +-2 B-scan distances across the half-line (so
// that near the centre, and at 61 B-scans everywhere, it spans B-scans on both sides). Larger
// windows measured no better: the error left is the fit's own (a plateau), not the samples'.
constexpr double kLocalFitRadialSteps = 4.0;
constexpr double kLocalFitTangentialBscans = 2.0;
// The centre's quadratic window under noise: the vertex's noise SD falls as sigma / R^2 (more
// nodes, longer lever) while the cubic terms of an asymmetric pit bias it by ~R, so the best R
// grows as sigma^(1/3); 0.2 mm at 1 axial pixel (3.87 um): measured 0.15 / 0.2 / 0.25 mm over
// 36 seeds alike within their scatter, 0.06 mm (the noise-free choice) worse.
constexpr double kNoisyCentreFitRadiusMm = 0.2;
constexpr double kOnePixelNoiseMm = 0.0038717;
// The pit floor's window: +-1.51 node spacings holds at least 3 B-scans and 3 A-scans wherever
// the centre lies between them.
constexpr double kFloorNodeSpans = 1.51;
// The CFT pass's centre sample under noise: a quadratic surface over this fraction of the
// centre window (measured: 0.5 keeps the CFT's and alpha_m's RMS within 6 % of the full
// window's and removes half to all of their deterministic bias; docs/algorithms/cube.md,
// session 44).
constexpr double kCentreSampleWindowFraction = 0.5;
double noisy_centre_fit_radius_mm(double sd_mm) {
    return kNoisyCentreFitRadiusMm * std::cbrt(sd_mm / kOnePixelNoiseMm);
}

// Under noise, about out.centre_mm (searched or given; fit_r the centre window's half-side):
// the pit floor for the radial samples the local fits cannot give, the smallest window centred
// on the centre that holds 3 A-scans and 3 B-scans (a quadratic in both directions), at least
// the noise-free centre window; and the CFT pass's centre sample, the height at the centre of
// the quadratic surface over half the centre window (at least the floor's). The centre window's
// vertex height is biased by the pit's higher-order terms, which grow with the window; the
// floor's own window removes more of that bias but adds noise (docs/algorithms/cube.md, session
// 44). Either left unset when its fit fails (the sample then stays the vertex height, if any).
void pit_floor_and_centre_sample(const ThicknessMap& m, const CubeParams& params, double fit_r,
                                 Centre& out) {
    const double fx = std::max(params.centre_fit_radius_mm, kFloorNodeSpans * m.dx_mm);
    const double fy = std::max(params.centre_fit_radius_mm, kFloorNodeSpans * m.dy_mm);
    if (const auto k = quadratic_surface(m, out.centre_mm, fx, fy)) {
        out.floor = PitFloor{.origin = out.centre_mm, .k = *k, .half_x_mm = fx, .half_y_mm = fy};
    }
    const double sw = kCentreSampleWindowFraction * fit_r;
    if (const auto k = quadratic_surface(m, out.centre_mm, std::max(fx, sw), std::max(fy, sw))) {
        out.sample_mm = (*k)(0);
    }
}

// ---- radial samples under noise (docs/algorithms/cube.md "Radial samples under noise") ------
// Window of one radial sample (r_k on half-line i): the valid nodes p with |(|p - c| - r_k)| <=
// radial_half_mm, on the half-line's side of the centre (p - c) . d_i > 0, and either inside
// its angular sector (anatomical angle within sector_half_rad of theta_i; with pi / n the
// sectors tile the plane, so every node serves one half-line) or within tangential_min_mm of
// the half-line (near the centre, where a sector holds too few nodes).
struct LocalFitWindow {
    double radial_half_mm = 0.0;
    double sector_half_rad = 0.0;
    double tangential_min_mm = 0.0;
    int min_nodes = 8;
};

// Model T = a + b rho + c rho^2 + e tau with rho = |p - c| - r_k (the radius: a rotationally
// symmetric map is then a function of rho alone, so the sector's width costs no bias for it)
// and tau = (p - c) . d_i^perp (linear: the map's change across the half-line cancels over a
// symmetric window to first order). Quadratic in rho: a symmetric window's local quadratic is
// unbiased for cubic profiles too, where a local linear fit errs by T'' h^2 / 6. The sample
// is a; a window with fewer than min_nodes nodes or a singular design keeps the bilinear value.
// Samples that are missing under cube.md step 3 (a missing bilinear neighbour) stay missing.
// The sums of one sample's normal equations for T = a + b rho + c rho^2 + e tau (f = (1, rho,
// rho^2, tau)): the 9 distinct entries of sum f f^T and the 4 of sum v f, added as scalars (the
// same products as a rank-one update of the 4x4 matrix, at a third of its cost here).
struct LocalFitSums {
    double n = 0, r1 = 0, r2 = 0, r3 = 0, r4 = 0, t1 = 0, r1t = 0, r2t = 0, t2 = 0;
    double v = 0, vr1 = 0, vr2 = 0, vt = 0;
    int count = 0;
    void add(double rho, double tau, double value) {
        const double rho2 = rho * rho;
        n += 1.0;
        r1 += rho;
        r2 += rho2;
        r3 += rho2 * rho;
        r4 += rho2 * rho2;
        t1 += tau;
        r1t += tau * rho;
        r2t += tau * rho2;
        t2 += tau * tau;
        v += value;
        vr1 += value * rho;
        vr2 += value * rho2;
        vt += value * tau;
        ++count;
    }
    [[nodiscard]] Eigen::Matrix4d normal() const {
        Eigen::Matrix4d a;
        a << n, r1, r2, t1, r1, r2, r3, r1t, r2, r3, r4, r2t, t1, r1t, r2t, t2;
        return a;
    }
    [[nodiscard]] Eigen::Vector4d rhs() const { return {v, vr1, vr2, vt}; }
};

// The local fit's value at grid point g from its window's sums, or nullopt when the window has
// fewer than min_nodes nodes, a singular design, or a value noisier than the bilinear sample's.
std::optional<double> local_fit_value(const LocalFitSums& q,
                                      const LocalFitWindow& win,
                                      const ThicknessMap& m,
                                      const V2& g) {
    using V4 = Eigen::Vector4d;
    if (q.count < win.min_nodes) return std::nullopt;
    const Eigen::LDLT<Eigen::Matrix4d> ldlt(q.normal());
    const auto d = ldlt.vectorD();
    if (ldlt.info() != Eigen::Success || !(d.minCoeff() > 1e-9 * d.maxCoeff())) {
        return std::nullopt;
    }
    // Noise of the fit's value: sigma^2 (N^-1)_00; the bilinear sample's: sigma^2 sum w^2 of its
    // 4 weights. Keep the less noisy (a window whose nodes barely span rho or tau extrapolates).
    const double var_fit = ldlt.solve(V4::UnitX())(0);
    const double u = g.x() / m.dx_mm - std::floor(g.x() / m.dx_mm);
    const double t = g.y() / m.dy_mm - std::floor(g.y() / m.dy_mm);
    const double var_bilinear = ((1.0 - u) * (1.0 - u) + u * u) * ((1.0 - t) * (1.0 - t) + t * t);
    if (!(var_fit < var_bilinear)) return std::nullopt;
    const double z = ldlt.solve(q.rhs())(0);
    return std::isfinite(z) ? std::optional<double>(z) : std::nullopt;
}

// With `sector_nodes` (size n), also hands every valid node within `sector_radius` of the centre
// to its own sector's list as (radius, thickness): the sector bins of the final fit.
void local_fit_samples(const ThicknessMap& m,
                       const V2& c,
                       const Eigen::Matrix2d& grid_to_anatomical,
                       const LocalFitWindow& win,
                       std::vector<CubeHalfLine>& lines,
                       std::vector<std::vector<V2>>* sector_nodes = nullptr,
                       double sector_radius = 0.0,
                       const PitFloor& floor = {}) {
    if (lines.empty() || lines.front().r_mm.size() < 2) return;
    const std::vector<double>& radii = lines.front().r_mm;
    const std::size_t n = lines.size();
    const std::size_t ns = radii.size();
    const double h = win.radial_half_mm;
    const double w = win.tangential_min_mm;
    const double s = radii[1];
    // Uniform radii k s for k < uniform; the last may be R itself (docs: "Radial resampling").
    const std::size_t uniform =
        std::fabs(radii.back() - static_cast<double>(ns - 1) * s) < 1e-9 ? ns : ns - 1;
    std::vector<LocalFitSums> sums(n * ns);
    std::vector<V2> dir(n);
    std::vector<V2> perp(n);
    for (std::size_t i = 0; i < n; ++i) {
        dir[i] = lines[i].direction;
        perp[i] = V2(-dir[i].y(), dir[i].x());
    }
    const double step = 2.0 * kPi / static_cast<double>(n);
    const double rmax = radii.back() + h;
    const int a0 = std::max(0, static_cast<int>(std::floor((c.x() - rmax) / m.dx_mm)));
    const int a1 = std::min(m.cols - 1, static_cast<int>(std::ceil((c.x() + rmax) / m.dx_mm)));
    const int b0 = std::max(0, static_cast<int>(std::floor((c.y() - rmax) / m.dy_mm)));
    const int b1 = std::min(m.rows - 1, static_cast<int>(std::ceil((c.y() + rmax) / m.dy_mm)));
    // Scaled coordinates keep the 4x4 normal equations well conditioned.
    const double inv_h = 1.0 / h;
    const double tau_scale = 1.0 / std::max(w, h);
    for (int b = b0; b <= b1; ++b) {
        for (int a = a0; a <= a1; ++a) {
            const double v = m.at(b, a);
            if (std::isnan(v)) continue;
            const V2 p(a * m.dx_mm - c.x(), b * m.dy_mm - c.y());
            const double r = p.norm();
            if (r > rmax || r <= 0.0) continue;
            std::size_t k_lo = static_cast<std::size_t>(std::max(1.0, std::ceil((r - h) / s)));
            std::size_t k_hi = static_cast<std::size_t>(std::max(0.0, std::floor((r + h) / s)));
            k_hi = std::min(k_hi, uniform - 1);
            const bool last = uniform < ns && std::fabs(r - radii.back()) <= h;
            if (k_lo > k_hi && !last) continue;
            const V2 pa = grid_to_anatomical * p;
            double phi = std::atan2(pa.y(), pa.x());
            if (phi < 0.0) phi += 2.0 * kPi;
            const auto i0 = static_cast<long>(std::lround(phi / step));
            if (sector_nodes != nullptr && r <= sector_radius) {
                (*sector_nodes)[static_cast<std::size_t>(i0) % n].emplace_back(r, v);
            }
            // Half-lines whose tangential band can hold the node (those more than 90 deg away
            // fail (p - c) . d_i > 0).
            const auto quarter = static_cast<long>(n / 4) + 1;
            const long reach =
                w >= r
                    ? quarter
                    : std::min(quarter, static_cast<long>(std::ceil(std::asin(w / r) / step)) + 1);
            for (long j = i0 - reach; j <= i0 + reach; ++j) {
                const auto i = static_cast<std::size_t>(
                    ((j % static_cast<long>(n)) + static_cast<long>(n)) % static_cast<long>(n));
                if (p.dot(dir[i]) <= 0.0) continue;
                const double tau = p.dot(perp[i]);
                // |phi - j step| wrapped into [0, pi] (|j - i0| <= n / 4 + 1: one turn at most).
                double dphi = std::fabs(phi - static_cast<double>(j) * step);
                if (dphi > kPi) dphi = 2.0 * kPi - dphi;
                const bool in_sector = dphi <= win.sector_half_rad;
                if (!in_sector && std::fabs(tau) > w) continue;
                const double tau_s = tau * tau_scale;
                auto add = [&](std::size_t k) {
                    sums[i * ns + k].add((r - radii[k]) * inv_h, tau_s, v);
                };
                for (std::size_t k = k_lo; k <= k_hi; ++k) add(k);
                if (last) add(ns - 1);
            }
        }
    }
    for (std::size_t i = 0; i < n; ++i) {
        for (std::size_t k = 1; k < ns; ++k) {
            if (std::isnan(lines[i].h_mm[k])) continue;
            const V2 g = c + radii[k] * dir[i];
            if (const auto z = local_fit_value(sums[i * ns + k], win, m, g)) {
                lines[i].h_mm[k] = *z;
            } else if (floor.holds(g)) {
                // No local fit here (near the centre its window holds one or two B-scans at
                // 61 B-scans): the pit floor's quadratic surface, not the bilinear sample, whose
                // interpolation across B-scans is biased upward in the convex pit.
                lines[i].h_mm[k] = floor.at(g);
            }
        }
    }
}

}  // namespace

namespace cube_detail {

double median(std::vector<double> v) {
    std::sort(v.begin(), v.end());
    const std::size_t n = v.size();
    return n % 2 == 1 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

// ---- the final fit's samples under noise: sector bins (docs/algorithms/cube.md "Radial
// samples under noise") -------------------------------------------------------------------------
// Every valid node p with 0 < |p - c| <= R belongs to the half-line nearest to its anatomical
// angle (sectors of +-180 deg / n: they tile the disk, every node serves exactly one half-line;
// local_fit_samples hands them over). A half-line's nodes, ordered by radius, are cut into runs of
// k consecutive nodes, k = round(count / K) >= 1 with K the number of regular samples of a
// half-line, and each run is one sample: the mean thickness of its nodes at the root-mean-square
// radius of its nodes. Equal runs give every sample the same noise (sigma^2 / k), so the unweighted
// fit weighs them alike; no node serves twice and nothing is smoothed across the radius. The RMS
// radius makes a run's mean exact for T = a + b r^2 (the pit floor, where a sector is narrow and a
// run spans up to ~0.15 mm: the mean radius would put the mean ~1 um too high there); where a run
// spans a few um, as elsewhere, the two radii differ by < 0.02 um. The last run takes the remainder
// (k to 2k - 1 nodes). A half-line with fewer than kMinSectorNodes nodes keeps its samples. Sample
// 0 stays the centre. With `profiles` (the CFT pass's fitted half-lines) each node is first moved
// along its half-line's profile T^ to the run's mean radius (v + T^(mean) - T^(r)) and the sample
// is their mean there: no T'' var(r) / 2 of the profile's curvature within a run (the RMS radius
// stays for a half-line whose CFT pass failed). Above 1 axial pixel of noise per surface the runs
// lengthen with noise_sd_mm (docs/algorithms/cube.md, "Bias under noise at 61 B-scans").
constexpr std::size_t kMinSectorNodes = 16;
// A half-line's fitted profile (fitted_thickness_mm) at radii that increase from call to call
// (a run's nodes, sorted): Newton on the segment's x(t) = r from the previous t, which the
// sorted radii keep close; bisection (solve_x) where Newton does not converge in a few steps
// (x'(t) = 0 at an end whose handle is 0). NaN outside [0, R] or on an invalid profile.
class ProfileAt {
public:
    explicit ProfileAt(const CubeHalfLine& h) : h_(h) {}
    double operator()(double r) {
        if (!h_.valid || h_.r_mm.empty() || r < 0.0 || r > h_.r_mm.back()) return kMissing;
        const bool interior = r <= h_.interior.control[3].x();
        const Ctrl& c = interior ? h_.interior.control : h_.exterior.control;
        if (r < c[0].x() || r > c[3].x()) return kMissing;
        double& t = interior ? t_interior_ : t_exterior_;
        bool converged = false;
        for (int it = 0; it < 8 && !converged; ++it) {
            const double dx = bezier_derivative(c, t).x();
            if (!(dx > 0.0)) break;
            const double step = (bezier_point(c, t).x() - r) / dx;
            t = std::clamp(t - step, 0.0, 1.0);
            converged = std::fabs(step) < 1e-13;
        }
        if (!converged) t = solve_x(c, r);
        return bezier_point(c, t).y();
    }

private:
    const CubeHalfLine& h_;
    double t_interior_ = 0.5;
    double t_exterior_ = 0.5;
};

// Above 1 axial pixel of noise per surface (node SD sqrt(2) x 3.87 um) the runs lengthen in
// proportion to the noise SD, up to 4x (docs/algorithms/cube.md, "Bias under noise").
constexpr double kOnePixelNodeSdMm = 0.0054754;
constexpr double kMaxRunFactor = 4.0;

void sector_bin_samples(std::vector<std::vector<V2>>& nodes,
                        std::vector<CubeHalfLine>& lines,
                        const std::vector<CubeHalfLine>* profiles,
                        double noise_sd_mm) {
    const double run_factor = std::clamp(noise_sd_mm / kOnePixelNodeSdMm, 1.0, kMaxRunFactor);
    const std::size_t n = lines.size();
    if (n == 0 || nodes.size() != n || lines.front().r_mm.size() < 2) return;
    const std::size_t regular = lines.front().r_mm.size() - 1;
    for (std::size_t i = 0; i < n; ++i) {
        std::vector<V2>& d = nodes[i];
        if (d.size() < kMinSectorNodes) continue;
        // By radius; equal radii by thickness, so that the runs do not depend on the scan order.
        std::sort(d.begin(), d.end(), [](const V2& x, const V2& y) {
            return x.x() < y.x() || (x.x() == y.x() && x.y() < y.y());
        });
        const std::size_t k = std::max<std::size_t>(
            1, static_cast<std::size_t>(
                   std::lround(run_factor * static_cast<double>(d.size()) /
                               static_cast<double>(regular))));
        const std::size_t runs = d.size() / k;
        CubeHalfLine& h = lines[i];
        h.r_mm.resize(1);
        h.h_mm.resize(1);
        const CubeHalfLine* profile =
            profiles != nullptr && profiles->size() == n && (*profiles)[i].valid ? &(*profiles)[i]
                                                                                 : nullptr;
        std::optional<ProfileAt> at;
        if (profile != nullptr) at.emplace(*profile);
        for (std::size_t j = 0; j < runs; ++j) {
            const std::size_t first = j * k;
            const std::size_t last = j + 1 == runs ? d.size() : first + k;
            double sum_h = 0.0;
            double sum_r = 0.0;
            double sum_r2 = 0.0;
            for (std::size_t q = first; q < last; ++q) {
                sum_h += d[q].y();
                sum_r += d[q].x();
                sum_r2 += d[q].x() * d[q].x();
            }
            const auto count = static_cast<double>(last - first);
            if (profile != nullptr) {
                // Every node moved along the profile to the run's mean radius.
                const double rho = sum_r / count;
                double shift = 0.0;
                for (std::size_t q = first; q < last; ++q) shift -= (*at)(d[q].x());
                shift += count * (*at)(rho);
                if (std::isfinite(shift)) {
                    h.r_mm.push_back(rho);
                    h.h_mm.push_back((sum_h + shift) / count);
                    continue;
                }
            }
            h.r_mm.push_back(std::sqrt(sum_r2 / count));
            h.h_mm.push_back(sum_h / count);
        }
    }
}

Centre find_centre(const CentreInput& in) {
    const ThicknessMap& m = in.map;
    const ScanGeometry& geo = in.geo;
    const CubeParams& params = in.params;
    const io::Scan& scan = in.scan;
    const bool noisy = in.noisy;
    const double noise_sd_mm = in.noise_sd_mm;
    const double width = (m.cols - 1) * m.dx_mm;
    const double height = (m.rows - 1) * m.dy_mm;
    Centre out;
    out.search_centre_mm = V2(0.5 * width, 0.5 * height);
    out.source = "scan centre";
    if (!in.line_scan && !scan.grids.empty()) {
        const auto& g = scan.grids.front();
        const V2 c = geo.slo_to_grid(V2(g.centre_x_slo_mm, g.centre_y_slo_mm));
        if (c.allFinite() && c.x() >= 0.0 && c.x() <= width && c.y() >= 0.0 && c.y() <= height) {
            out.search_centre_mm = c;
            out.source = "device thickness grid";
        } else {
            out.notes.push_back(
                "the device grid centre lies outside the scan: searched around "
                "the scan centre");
        }
    }
    if (params.centre_mm) {
        out.centre_mm = *params.centre_mm;
        out.source = "given";
        out.cft_mm = m.sample(out.centre_mm.x(), out.centre_mm.y());
        out.num_tied_minima = 0;
        if (std::isnan(out.cft_mm)) throw AnalysisError("no valid thickness at the given centre");
        // Under noise the same pit floor and centre sample as about a searched centre, so that
        // a given centre changes the centre alone (validation: docs/algorithms/cube.md).
        if (noisy && params.centre_fit_radius_mm > 0.0) {
            pit_floor_and_centre_sample(
                m, params,
                std::max(params.centre_fit_radius_mm, noisy_centre_fit_radius_mm(noise_sd_mm)), out);
        }
    } else {
        const double rs = params.search_radius_mm;
        // The node box around the search circle; values: M smoothed for the search (the
        // minimum of Eq. 7.13 on the smoothed map; docs/algorithms/cube.md "Centre").
        const V2& sc = out.search_centre_mm;
        NodeBox bx;
        bx.a0 = std::clamp(static_cast<int>(std::floor((sc.x() - rs) / m.dx_mm)), 0, m.cols - 1);
        bx.a1 = std::clamp(static_cast<int>(std::ceil((sc.x() + rs) / m.dx_mm)), 0, m.cols - 1);
        if (m.rows > 1) {
            bx.b0 =
                std::clamp(static_cast<int>(std::floor((sc.y() - rs) / m.dy_mm)), 0, m.rows - 1);
            bx.b1 = std::clamp(static_cast<int>(std::ceil((sc.y() + rs) / m.dy_mm)), 0, m.rows - 1);
        }
        const std::vector<double> sm = smoothed_box(m, bx, params.centre_smoothing_mm);
        auto value = [&](int b, int a) {
            return sm[static_cast<std::size_t>((b - bx.b0) * bx.cols() + (a - bx.a0))];
        };
        double best = std::numeric_limits<double>::infinity();
        for (int b = bx.b0; b <= bx.b1; ++b) {
            for (int a = bx.a0; a <= bx.a1; ++a) {
                const double v = value(b, a);
                if (std::isnan(v)) continue;
                if ((V2(a * m.dx_mm, b * m.dy_mm) - sc).norm() > rs) continue;
                best = std::min(best, v);
            }
        }
        if (!std::isfinite(best)) {
            throw AnalysisError("no valid thickness within " + std::to_string(rs) +
                                " mm of the search centre: the fovea cannot be located");
        }
        std::vector<double> xs;
        std::vector<double> ys;
        for (int b = bx.b0; b <= bx.b1; ++b) {
            for (int a = bx.a0; a <= bx.a1; ++a) {
                const double v = value(b, a);
                if (std::isnan(v) || v > best + params.tie_tolerance_mm) continue;
                const V2 q(a * m.dx_mm, b * m.dy_mm);
                if ((q - sc).norm() > rs) continue;
                xs.push_back(q.x());
                ys.push_back(q.y());
            }
        }
        out.num_tied_minima = static_cast<int>(xs.size());
        const V2 node_centre(median(xs), median(ys));  // Eq. 7.13, component-wise median
        out.centre_mm = node_centre;
        if (params.centre_fit_radius_mm > 0.0) {
            // Between the nodes: the vertex of a quadratic fitted to M around the minimum (the
            // window spans at least the neighbouring B-scans). Under noise the window widens
            // with sigma^(1/3) (docs/algorithms/cube.md "Radial samples under noise").
            double fit_r = params.centre_fit_radius_mm;
            if (noisy) fit_r = std::max(fit_r, noisy_centre_fit_radius_mm(noise_sd_mm));
            out.fit_radius_mm = fit_r;
            const double rx = std::max(fit_r, 1.01 * m.dx_mm);
            const double ry = std::max(fit_r, 1.01 * m.dy_mm);
            double vertex_mm = kMissing;
            if (const auto v = quadratic_vertex(m, out.centre_mm, rx, ry, &vertex_mm)) {
                out.centre_mm = *v;
                if (noisy) out.sample_mm = vertex_mm;
            }
            if (noisy) pit_floor_and_centre_sample(m, params, fit_r, out);
        }
        double cv = m.sample(out.centre_mm.x(), out.centre_mm.y());
        if (std::isnan(cv) && out.centre_mm != node_centre) {
            // Missing values next to the refined centre: keep the minimum's node centre.
            out.centre_mm = node_centre;
            out.sample_mm = kMissing;
            out.floor = PitFloor{};
            cv = m.sample(node_centre.x(), node_centre.y());
            out.notes.push_back(
                "missing thickness next to the refined centre: the centre is the "
                "minimum's node position");
        }
        if (std::isnan(cv)) {
            // Still missing around it (bilinear needs four valid nodes): the valid minimum node
            // nearest the median, with its own value.
            double best_d = std::numeric_limits<double>::infinity();
            for (std::size_t k = 0; k < xs.size(); ++k) {
                const int a = static_cast<int>(std::lround(xs[k] / m.dx_mm));
                const int b = m.rows > 1 ? static_cast<int>(std::lround(ys[k] / m.dy_mm)) : 0;
                const double raw = m.at(b, a);
                const double d = (V2(xs[k], ys[k]) - node_centre).norm();
                if (!std::isnan(raw) && d < best_d) {
                    best_d = d;
                    out.centre_mm = V2(xs[k], ys[k]);
                    out.floor = PitFloor{};
                    cv = raw;
                }
            }
            if (std::isnan(cv)) throw AnalysisError("no valid thickness at the centre found");
            out.notes.push_back(
                "missing thickness around the minimum: CFT is the value of the "
                "nearest valid minimum node");
        }
        out.cft_mm = cv;
        const double step = std::max(m.dx_mm, m.dy_mm);
        if ((out.centre_mm - out.search_centre_mm).norm() > rs - step) {
            out.qc_flags.push_back("centre at search border");
        }
    }
    return out;
}

RadialSamples radial_samples(const ThicknessMap& m,
                             const ScanGeometry& geo,
                             const CubeParams& params,
                             const V2& centre_mm,
                             double cft_mm,
                             double scale_x_mm,
                             bool line_scan,
                             bool noisy,
                             const PitFloor& floor) {
    RadialSamples out;
    const double spacing = params.sample_spacing_mm > 0.0 ? params.sample_spacing_mm : scale_x_mm;
    out.spacing_mm = spacing;
    std::vector<double>& radii = out.radii;
    const int K = static_cast<int>(std::floor(params.radius_mm / spacing + 1e-9));
    for (int k = 0; k <= K; ++k) radii.push_back(k * spacing);
    if (params.radius_mm - K * spacing > 1e-9) radii.push_back(params.radius_mm);

    const int n = line_scan ? 2 : params.num_half_lines;
    const Eigen::Matrix2d to_grid = geo.grid_to_anatomical().inverse();
    for (int i = 0; i < n; ++i) {
        CubeHalfLine h;
        h.angle_deg = 360.0 * i / n;
        const double th = h.angle_deg / kDeg;
        if (line_scan) {
            // Nasal (0 deg) is along grid +x when the line's +x points nasally.
            const double sx = geo.x_is_nasal() ? 1.0 : -1.0;
            h.direction = V2(i == 0 ? sx : -sx, 0.0);
        } else {
            h.direction = (to_grid * V2(std::cos(th), std::sin(th))).normalized();
        }
        h.r_mm = radii;
        h.h_mm.resize(radii.size());
        for (std::size_t k = 0; k < radii.size(); ++k) {
            const V2 q = centre_mm + radii[k] * h.direction;
            h.h_mm[k] = k == 0 ? cft_mm : m.sample(q.x(), line_scan ? 0.0 : q.y());
            if (std::isnan(h.h_mm[k])) ++h.num_missing;
        }
        out.half_lines.push_back(std::move(h));
    }
    // Under segmentation noise the samples are local fits over every node of their sector
    // (docs/algorithms/cube.md "Radial samples under noise"); the bilinear ones are kept for
    // the RMSE.
    out.sector_nodes.resize(noisy ? out.half_lines.size() : 0);
    if (noisy) {
        for (const auto& h : out.half_lines) out.bilinear.push_back(h.h_mm);
        LocalFitWindow win;
        win.radial_half_mm = kLocalFitRadialSteps * std::max(spacing, m.dx_mm);
        win.sector_half_rad = kPi / n;
        win.tangential_min_mm = kLocalFitTangentialBscans * m.dy_mm;
        local_fit_samples(m, centre_mm, geo.grid_to_anatomical(), win, out.half_lines,
                          &out.sector_nodes, params.radius_mm, floor);
        out.noise_adaptive = true;
    }
    return out;
}

}  // namespace cube_detail

double ThicknessMap::sample(double x_mm, double y_mm) const {
    if (cols < 2 || dx_mm <= 0.0) return kMissing;
    const double fa = x_mm / dx_mm;
    if (!(fa >= 0.0) || fa > cols - 1) return kMissing;
    int a0 = static_cast<int>(std::floor(fa));
    if (a0 >= cols - 1) a0 = cols - 2;
    const double u = fa - a0;
    if (rows == 1) {
        if (std::fabs(y_mm) > 1e-9) return kMissing;
        const double v0 = at(0, a0);
        const double v1 = at(0, a0 + 1);
        if (std::isnan(v0) || std::isnan(v1)) return kMissing;
        return (1.0 - u) * v0 + u * v1;
    }
    if (dy_mm <= 0.0) return kMissing;
    const double fb = y_mm / dy_mm;
    if (!(fb >= 0.0) || fb > rows - 1) return kMissing;
    int b0 = static_cast<int>(std::floor(fb));
    if (b0 >= rows - 1) b0 = rows - 2;
    const double v = fb - b0;
    const double m00 = at(b0, a0);
    const double m01 = at(b0, a0 + 1);
    const double m10 = at(b0 + 1, a0);
    const double m11 = at(b0 + 1, a0 + 1);
    // cube.md step 3: a sample whose four neighbours are not all valid is missing.
    if (std::isnan(m00) || std::isnan(m01) || std::isnan(m10) || std::isnan(m11)) return kMissing;
    return (1.0 - v) * ((1.0 - u) * m00 + u * m01) + v * ((1.0 - u) * m10 + u * m11);
}

ThicknessMap cube_detail::thickness_map_of_lines(const io::Scan& scan, int upper, int lower) {
    ThicknessMap m;
    m.rows = scan.num_bscans();
    m.cols = scan.meta.size_x;
    m.dx_mm = scan.meta.scale_x_mm;
    m.dy_mm = m.rows > 1 ? scan.meta.distance_mm : 0.0;
    if (m.rows < 1 || m.cols < 2) throw AnalysisError("the scan holds no B-scans to analyse");
    const std::string up = scan.line_name(upper);
    const std::string low = scan.line_name(lower);
    if (upper < 0 || lower < 0 || scan.num_lines() <= std::max(upper, lower)) {
        throw AnalysisError("the export has no " + up + " and " + low +
                            " segmentation (needed for thickness)");
    }
    if (scan.valid_fraction(lower) == 0.0) {
        throw AnalysisError("the " + low + " segmentation is missing everywhere (needed for thickness)");
    }
    if (scan.valid_fraction(upper) == 0.0) {
        throw AnalysisError("the " + up + " segmentation is missing everywhere (needed for thickness)");
    }
    const auto ku = static_cast<std::size_t>(upper);
    const auto kl = static_cast<std::size_t>(lower);
    const double sz = scan.meta.scale_z_mm;
    // A boundary lies in the image when its depth is within [0, SizeZ] pixels (a boundary at
    // the bottom edge is depth SizeZ); a scan without a known depth is not checked.
    const auto depth_px = static_cast<float>(scan.meta.size_z);
    const auto inside = [depth_px](float d) {
        return depth_px <= 0.0F || (d >= 0.0F && d <= depth_px);
    };
    m.mm.assign(static_cast<std::size_t>(m.rows) * static_cast<std::size_t>(m.cols), kMissing);
    for (int b = 0; b < m.rows; ++b) {
        const auto& bs = scan.bscans[static_cast<std::size_t>(b)];
        for (int a = 0; a < m.cols; ++a) {
            const auto i = static_cast<std::size_t>(a);
            const float di = i < bs.seg[ku].size() ? bs.seg[ku][i] : io::kNoPixelData;
            const float db = i < bs.seg[kl].size() ? bs.seg[kl][i] : io::kNoPixelData;
            double v = kMissing;
            // Height z = -depth * ScaleZ, so ILM - BM = (depth_BM - depth_ILM) * ScaleZ.
            if (io::is_valid(di) && io::is_valid(db) && di < io::kInvalidThreshold &&
                db < io::kInvalidThreshold) {
                if (!inside(di) || !inside(db)) {
                    ++m.num_outside_image;
                } else if (db < di) {
                    ++m.num_inverted;
                } else {
                    v = (static_cast<double>(db) - static_cast<double>(di)) * sz;
                }
            }
            if (std::isnan(v)) ++m.num_missing;
            m.mm[static_cast<std::size_t>(b) * static_cast<std::size_t>(m.cols) + i] = v;
        }
    }
    if (static_cast<std::size_t>(m.num_missing) == m.mm.size()) {
        throw AnalysisError(
            "no A-scan has both an " + up + " and a " + low + " inside the image with the " + up +
            " above the " + low + " (" +
            std::to_string(m.num_outside_image) + " outside the image, " +
            std::to_string(m.num_inverted) + " with the " + up + " below the " + low + ")");
    }
    return m;
}

ThicknessMap thickness_map(const io::Scan& scan) {
    return thickness_map_of_lines(scan, static_cast<int>(io::Layer::kILM),
                                  static_cast<int>(io::Layer::kBM));
}

double thickness_noise_sd(const ThicknessMap& m) {
    std::vector<double> second;
    second.reserve(static_cast<std::size_t>(m.rows) * static_cast<std::size_t>(m.cols));
    for (int b = 0; b < m.rows; ++b) {
        for (int a = 1; a + 1 < m.cols; ++a) {
            const double v = m.at(b, a - 1) - 2.0 * m.at(b, a) + m.at(b, a + 1);
            if (std::isfinite(v)) second.push_back(std::fabs(v));
        }
    }
    if (second.size() < 16) return 0.0;
    const auto mid = second.begin() + static_cast<std::ptrdiff_t>(second.size() / 2);
    std::nth_element(second.begin(), mid, second.end());
    return 1.4826 * *mid / std::sqrt(6.0);
}

}  // namespace octshape::retina
