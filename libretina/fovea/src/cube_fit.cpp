// CuBe fovea analysis, the Bézier fit (thesis §7.1-7.2, docs/algorithms/cube.md steps 4-5): the
// interior and exterior cubic curves of one half-line, alone or jointly at the rim, by alternating
// foot points and constrained least squares. Decisions: docs/algorithms/cube.md.

#include <Eigen/Dense>
#include <algorithm>
#include <bit>
#include <cmath>
#include <optional>
#include <string>

#include "cube_stages.h"
#include "octshape/error.h"
#include "octshape/retina/cube.h"

namespace octshape::retina {
using namespace cube_detail;
namespace {

struct Bernstein {
    double b0, b1, b2, b3;
};
Bernstein bernstein(double t) {
    const double s = 1.0 - t;
    return {s * s * s, 3.0 * t * s * s, 3.0 * t * t * s, t * t * t};
}

// Minimises z^T H z - 2 g^T z over the triangle (v0, v1, v2): the unconstrained minimum when it
// lies inside, else the best point on the edges (a convex quadratic's constrained minimum lies
// on the boundary when the free one is outside).
V2 minimise_on_triangle(const Eigen::Matrix2d& H, const V2& g, const std::array<V2, 3>& v) {
    auto f = [&](const V2& z) { return z.dot(H * z) - 2.0 * g.dot(z); };
    const double det = H.determinant();
    const double scale = H.trace() * H.trace();
    if (det > 1e-12 * scale && scale > 0.0) {
        const V2 z = H.inverse() * g;
        // Barycentric inside test.
        Eigen::Matrix2d T;
        T.col(0) = v[1] - v[0];
        T.col(1) = v[2] - v[0];
        const V2 l = T.inverse() * (z - v[0]);
        const double eps = 1e-12;
        if (l.x() >= -eps && l.y() >= -eps && l.x() + l.y() <= 1.0 + eps) return z;
    }
    V2 best = v[0];
    double best_f = f(v[0]);
    for (int e = 0; e < 3; ++e) {
        const V2& a = v[static_cast<std::size_t>(e)];
        const V2& b = v[static_cast<std::size_t>((e + 1) % 3)];
        const V2 d = b - a;
        const double qa = d.dot(H * d);
        const double qb = 2.0 * (d.dot(H * a) - g.dot(d));
        const double u = qa > 0.0 ? std::clamp(-qb / (2.0 * qa), 0.0, 1.0) : 0.0;
        for (const double cand : {u, 0.0, 1.0}) {
            const V2 z = a + cand * d;
            const double fz = f(z);
            if (fz < best_f) {
                best_f = fz;
                best = z;
            }
        }
    }
    return best;
}

// A cubic in the power basis, Q(t) = a + t (b + t (c + t e)) (Horner): the same polynomial as
// the Bernstein form to rounding, at a third of the cost of three Bernstein sums.
struct PowerBasis {
    V2 a, b, c, e;
    explicit PowerBasis(const Ctrl& p)
        : a(p[0]),
          b(3.0 * (p[1] - p[0])),
          c(3.0 * (p[2] - 2.0 * p[1] + p[0])),
          e(p[3] - 3.0 * p[2] + 3.0 * p[1] - p[0]) {}
    V2 point(double x) const { return a + x * (b + x * (c + x * e)); }
};

// Sum of squared distances of samples [first, last) to their points Q(t_k). Every energy that
// is compared with another (the fits' stopping and step tests) is summed this way, in this
// order, so that the comparisons see the same rounding.
double squared_distances(std::span<const V2> d,
                         const PowerBasis& q,
                         std::span<const double> t,
                         std::size_t first,
                         std::size_t last) {
    double e = 0.0;
    for (std::size_t k = first; k < last; ++k) e += (q.point(t[k]) - d[k]).squaredNorm();
    return e;
}

// Foot point of samples [first, last) on the curve (Eq. 7.10): Newton on (Q(t) - D) . Q'(t) = 0,
// started from the previous t, kept in [t_{k-1}, 1] (k = 0: [0, 1]) so that t stays monotone.
// Samples outside the range keep their t (end samples that are end control points: 0 and 1).
// Returns the samples' squared distances at their new t, summed as squared_distances does.
double update_foot_points(std::span<const V2> d,
                          const Ctrl& p,
                          std::span<double> t,
                          std::size_t first,
                          std::size_t last) {
    const PowerBasis pb(p);
    const V2 two_c = 2.0 * pb.c;
    const V2 three_e = 3.0 * pb.e;
    const V2 six_e = 6.0 * pb.e;
    double sum = 0.0;
    for (std::size_t k = first; k < last; ++k) {
        const double lo = k > 0 ? t[k - 1] : 0.0;
        const double tk = std::max(t[k], lo);
        V2 q = pb.point(tk) - d[k];
        const double start_dist = q.squaredNorm();
        double x = tk;
        for (int it = 0; it < 12; ++it) {
            const V2 q1 = pb.b + x * (two_c + x * three_e);
            const V2 q2 = two_c + x * six_e;
            const double f = q.dot(q1);
            double fp = q1.squaredNorm() + q.dot(q2);
            if (fp <= 0.0) fp = q1.squaredNorm();  // Gauss-Newton where Newton is not a descent
            if (fp <= 1e-300) break;
            const double nx = std::clamp(x - f / fp, lo, 1.0);
            // Newton converges quadratically: after a step of size s the error left is ~M s^2,
            // M = f''/(2 f') ~ 1.5 |Q''| / |Q'| <= ~50 on these curves, so a step below 1e-6
            // leaves <= ~5e-11 in t. The energy is stationary in t at the foot point: that
            // costs ~|Q'|^2 (5e-11)^2 < 1e-20 mm^2 per sample, < 1e-3 of the stopping test's
            // 1e-10 relative change over ~170 samples at the ~1e-4 mm^2 energy of a noisy
            // half-line. (The earlier
            // 1e-15 stop spent a third more iterations confirming what was known.)
            const bool done = std::fabs(nx - x) < 1e-6;
            x = nx;
            q = pb.point(x) - d[k];
            if (done) break;
        }
        const double dist = q.squaredNorm();
        if (dist <= start_dist) {
            t[k] = x;
            sum += dist;
        } else {
            t[k] = tk;
            sum += start_dist;
        }
    }
    return sum;
}

std::vector<double> chord_length(std::span<const V2> d) {
    const std::size_t m = d.size();
    std::vector<double> t(m, 0.0);
    if (m < 2) return t;
    for (std::size_t k = 1; k < m; ++k) t[k] = t[k - 1] + (d[k] - d[k - 1]).norm();
    const double total = t[m - 1];
    for (auto& v : t) v = total > 0.0 ? v / total : 0.0;
    t[m - 1] = 1.0;
    return t;
}

// Weight of the tangential error in the squared-distance model of step (a) (see below).
constexpr double kTangentWeight = 0.0;

// Per-sample quadratic model of the squared distance used by step (a): with t fixed, the error
// e = Q(t_k) - D_k is measured as (e.N)^2 + w (e.T)^2 in the frame (T, N) of the current curve
// at the foot point (tangent-distance minimisation, Wang, Pottmann & Liu 2006). w = 1 is the
// plain point distance of Eq. 7.8: that alternation converges linearly and needs ~2000 rounds
// on exact Bezier data (RMSE 1.6 um after 100 rounds). w = 0 converges in 5-10 rounds on
// phantoms and real data (measured: w = 0.1 and 0.01 stall on long flat exteriors). A round
// whose Eq. 7.8 energy would rise falls back to the plain step; the energy monitored, the
// stopping rule and the reported RMSE are always Eq. 7.8's.
std::vector<Eigen::Matrix2d> distance_weights(std::span<const V2> d,
                                              const Ctrl* curve,
                                              const std::vector<double>& t,
                                              double tangent_weight) {
    std::vector<Eigen::Matrix2d> w(d.size(), Eigen::Matrix2d::Identity());
    if (curve == nullptr || tangent_weight >= 1.0) return w;
    for (std::size_t k = 0; k < d.size(); ++k) {
        const V2 q1 = bezier_derivative(*curve, t[k]);
        if (q1.norm() <= 1e-12) continue;
        const V2 tan = q1.normalized();
        const V2 nor(-tan.y(), tan.x());
        w[k] = nor * nor.transpose() + tangent_weight * tan * tan.transpose();
    }
    return w;
}

template <class Solve>
BezierFit alternate(std::span<const V2> d, const FitSettings& s, Solve solve) {
    BezierFit fit;
    fit.num_samples = static_cast<int>(d.size());
    fit.t = chord_length(d);
    const std::size_t n = d.size();
    // Step (b) for control points c: the foot points of the inner samples, then the Eq. 7.8
    // energy (the end samples keep t = 0 and 1).
    const auto project = [&](const Ctrl& c, std::vector<double>& t) {
        const PowerBasis q(c);
        const double first = squared_distances(d, q, t, 0, 1);
        const double inner = update_foot_points(d, c, t, 1, n - 1);
        return first + inner + squared_distances(d, q, t, n - 1, n);
    };
    double prev = std::numeric_limits<double>::infinity();
    bool have_curve = false;
    for (int round = 1; round <= s.max_rounds; ++round) {
        // (a) Eq. 7.9 (resp. its exterior analogue) with t fixed; (b) Eq. 7.10 foot points.
        const Ctrl* cur = have_curve ? &fit.control : nullptr;
        Ctrl c = solve(fit.t, distance_weights(d, cur, fit.t, kTangentWeight));
        std::vector<double> t = fit.t;
        double e = project(c, t);
        // The tangent model's step is a Gauss-Newton step with the foot points eliminated;
        // where the full step overshoots, shorter steps along it usually still descend (the
        // graph constraints are linear in the control points, so the segment stays feasible).
        for (double f = 0.5; have_curve && e > prev && f >= 1.0 / 64.0; f *= 0.5) {
            Ctrl cf;
            for (std::size_t i = 0; i < cf.size(); ++i) {
                cf[i] = fit.control[i] + f * (c[i] - fit.control[i]);
            }
            std::vector<double> tf = fit.t;
            const double ef = project(cf, tf);
            if (ef <= prev) {
                c = cf;
                t = std::move(tf);
                e = ef;
            }
        }
        if (e > prev) {  // the tangent model overshot: take the plain point-distance step
            c = solve(fit.t, distance_weights(d, nullptr, fit.t, 1.0));
            t = fit.t;
            e = project(c, t);
        }
        fit.rounds = round;
        if (e > prev) break;  // no step lowers the energy: at the minimum to rounding
        double step = std::numeric_limits<double>::infinity();
        if (have_curve) {
            step = 0.0;
            for (std::size_t i = 0; i < c.size(); ++i) {
                step = std::max(step, (c[i] - fit.control[i]).cwiseAbs().maxCoeff());
            }
        }
        fit.control = c;
        fit.t = std::move(t);
        fit.sse_mm2 = e;
        have_curve = true;
        // Converged: the energy (cube.md step 5), or no control point moves by 1e-7 mm (0.1 nm).
        if (e <= 1e-30 || (round > 1 && std::fabs(prev - e) <= s.energy_tolerance * prev) ||
            step < 1e-7) {
            fit.converged = true;
            break;
        }
        prev = e;
    }
    if (fit.rounds < s.max_rounds && !fit.converged) fit.converged = true;
    return fit;
}

// ---- the rim point as a model estimate (docs/algorithms/cube.md "Rim point") ---------------
// Unknowns q = (alpha, beta, h_rim, alpha_ext, P2x_ext, P2y_ext, r_rim, P0.y). With the foot
// points fixed both curves are linear in q: interior (Eq. 7.7) P0 = (0, P0.y), P0 + alpha (1,0),
// (r_rim - beta, h_rim), (r_rim, h_rim); exterior (Eq. 7.11) (r_rim, h_rim), (r_rim + alpha_ext,
// h_rim), P2_ext, P3. r_rim is pinned to the maximum sample (RimPoint::kMaximum, cube.md step 4) or
// free (kFit); P0.y is free only in the CFT pass and otherwise pinned to the shared CFT.
constexpr int kJoint = 8;
constexpr int kJointConstraints = 8;
using VJ = Eigen::Matrix<double, kJoint, 1>;
using MJ = Eigen::Matrix<double, kJoint, kJoint>;
using CJ = Eigen::Matrix<double, kJointConstraints, kJoint>;
using BJ = Eigen::Matrix<double, kJointConstraints, 1>;
using Kkt = Eigen::Matrix<double,
                          Eigen::Dynamic,
                          Eigen::Dynamic,
                          0,
                          kJoint + kJointConstraints,
                          kJoint + kJointConstraints>;
using KktVec = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, kJoint + kJointConstraints, 1>;

struct JointGeometry {
    V2 p0;         // interior P0 = (0, CFT)
    V2 p3;         // exterior P3 = the last sample
    double r_min;  // bounds of a free rim radius q(6): the third and the fourth-last sample
    double r_max;
    double r_start;  // the maximum sample's radius (the start, and q(6) when pinned)
    bool free_rim;   // q(6) = r_rim is an unknown or pinned to r_start
    bool free_p0y;   // q(7) = P0.y is an unknown (the CFT pass) or pinned to p0.y
};

Ctrl joint_interior(const VJ& q, const JointGeometry& g) {
    const V2 p0(g.p0.x(), q(7));
    return {p0, p0 + V2(q(0), 0.0), V2(q(6) - q(1), q(2)), V2(q(6), q(2))};
}
Ctrl joint_exterior(const VJ& q, const JointGeometry& g) {
    return {V2(q(6), q(2)), V2(q(6) + q(3), q(2)), V2(q(4), q(5)), g.p3};
}

// Graph constraints C q <= b: alpha, beta >= 0, alpha + beta <= r_rim - P0.x (interior x
// monotone); alpha_ext >= 0, r_rim + alpha_ext <= P2x_ext <= P3.x (exterior x monotone).
void joint_constraints(const JointGeometry& geo, CJ& C, BJ& b) {
    C.setZero();
    b.setZero();
    C(0, 0) = -1.0;
    C(1, 1) = -1.0;
    C(2, 0) = 1.0;
    C(2, 1) = 1.0;
    C(2, 6) = -1.0;
    b(2) = -geo.p0.x();
    C(3, 3) = -1.0;
    C(4, 3) = 1.0;
    C(4, 4) = -1.0;
    C(4, 6) = 1.0;
    C(5, 4) = 1.0;
    b(5) = geo.p3.x();
    C(6, 6) = -1.0;
    b(6) = -geo.r_min;
    C(7, 6) = 1.0;
    b(7) = geo.r_max;
}

// Minimises q^T H q / 2 - g^T q subject to C q <= b (convex). For an active set S the KKT
// system H q + C_S^T l = g, C_S q = b_S gives a candidate; one that is feasible with l >= 0 is
// the global minimum (KKT conditions of a convex problem). Tried: no constraint, the previous
// round's active set `mask`, then every set by size. When none qualifies (degenerate H), the
// best feasible candidate, or `fallback` (feasible), is returned. `mask` returns the set used.
VJ minimise_joint_qp(
    const MJ& H, const VJ& g, const CJ& C, const BJ& b, const VJ& fallback, unsigned& mask) {
    const double tol = 1e-12;
    auto feasible = [&](const VJ& q) { return ((C * q - b).array() <= tol).all(); };
    auto f = [&](const VJ& q) { return 0.5 * q.dot(H * q) - g.dot(q); };
    VJ best = fallback;
    double best_f = f(fallback);
    unsigned best_mask = mask;
    // Returns true when the set's KKT point is the minimum.
    auto try_set = [&](unsigned set) {
        const int m = std::popcount(set);
        Kkt K = Kkt::Zero(kJoint + m, kJoint + m);
        KktVec rhs = KktVec::Zero(kJoint + m);
        K.topLeftCorner(kJoint, kJoint) = H;
        rhs.head(kJoint) = g;
        int row = 0;
        for (int c = 0; c < kJointConstraints; ++c) {
            if ((set & (1U << c)) == 0U) continue;
            K.block(kJoint + row, 0, 1, kJoint) = C.row(c);
            K.block(0, kJoint + row, kJoint, 1) = C.row(c).transpose();
            rhs(kJoint + row) = b(c);
            ++row;
        }
        const Eigen::FullPivLU<Kkt> lu(K);
        if (!lu.isInvertible()) return false;
        const KktVec z = lu.solve(rhs);
        const VJ q = z.head(kJoint);
        if (!z.allFinite() || !feasible(q)) return false;
        const double fq = f(q);
        if (fq < best_f) {
            best_f = fq;
            best = q;
            best_mask = set;
        }
        const double lscale = 1e-9 * (g.norm() + 1e-300);
        return m == 0 || (z.tail(m).array() >= -lscale).all();
    };
    if (try_set(0U) || (mask != 0U && try_set(mask))) {
        mask = best_mask;
        return best;
    }
    for (int size = 1; size <= kJointConstraints; ++size) {
        for (unsigned set = 1; set < (1U << kJointConstraints); ++set) {
            if (std::popcount(set) != size || set == mask) continue;
            if (try_set(set)) {
                mask = best_mask;
                return best;
            }
        }
    }
    mask = best_mask;
    return best;
}

struct JointState {
    VJ q = VJ::Zero();
    unsigned active = 0;    // the active constraints of the last step (a)
    std::vector<double> t;  // foot point of each sample on its own segment
    std::size_t split = 0;  // samples [0, split) are the interior's (x <= rim radius)
    double energy = 0.0;
};

// Samples [0, split) belong to the interior (the rim sample last), [split, n) to the exterior.
// Summed in the grouping project_joint gets it: the centre sample (t = 0), the interior's
// other samples, the exterior's but the last, the last (t = 1).
double joint_energy(std::span<const V2> d, const JointGeometry& geo, const JointState& s) {
    const std::size_t n = d.size();
    const PowerBasis qi(joint_interior(s.q, geo));
    const PowerBasis qe(joint_exterior(s.q, geo));
    return squared_distances(d, qi, s.t, 0, 1) + squared_distances(d, qi, s.t, 1, s.split) +
           squared_distances(d, qe, s.t, s.split, n - 1) + squared_distances(d, qe, s.t, n - 1, n);
}

// Step (b) for the control points next.q: foot points started from cur.t (Eq. 7.10), then the
// Eq. 7.8 energy.
void project_joint(std::span<const V2> d,
                   const JointGeometry& geo,
                   const JointState& cur,
                   JointState& next) {
    const std::size_t n = d.size();
    next.t = cur.t;
    std::size_t split = 1;
    while (split < n - 1 && d[split].x() <= next.q(6)) ++split;
    for (std::size_t k = std::min(split, cur.split); k < std::max(split, cur.split); ++k) {
        next.t[k] = k < split ? 1.0 : 0.0;  // changed segment: start from the rim end
    }
    next.split = split;
    const std::span<double> t(next.t);
    const Ctrl ci = joint_interior(next.q, geo);
    const Ctrl ce = joint_exterior(next.q, geo);
    const double centre = squared_distances(d, PowerBasis(ci), t, 0, 1);
    const double interior = update_foot_points(d, ci, t.subspan(0, split), 1, split);
    const double exterior =
        update_foot_points(d.subspan(split), ce, t.subspan(split), 0, n - split - 1);
    next.energy = centre + interior + exterior + squared_distances(d, PowerBasis(ce), t, n - 1, n);
}

// The Gauss-Newton normal equations H q = g of step (a) at `cur` (Eq. 7.9 for both segments,
// with the tangent weight of distance_weights).
void normal_equations(std::span<const V2> d,
                      const JointGeometry& geo,
                      const JointState& cur,
                      double tangent_weight,
                      MJ& H,
                      VJ& g) {
    const std::size_t n = d.size();
    const std::size_t split = cur.split;
    const Ctrl ci = joint_interior(cur.q, geo);
    const Ctrl ce = joint_exterior(cur.q, geo);
    H.setZero();
    g.setZero();
    for (std::size_t k = 0; k < n; ++k) {
        const bool in = k < split;
        const double t = cur.t[k];
        const Bernstein bb = bernstein(t);
        Eigen::Matrix<double, 2, kJoint> A = Eigen::Matrix<double, 2, kJoint>::Zero();
        V2 c0;  // the part of Q(t) that does not depend on q
        if (in) {
            A(0, 0) = bb.b1;
            A(0, 1) = -bb.b2;
            A(1, 2) = bb.b2 + bb.b3;
            A(0, 6) = bb.b2 + bb.b3;
            A(1, 7) = bb.b0 + bb.b1;
            c0 = V2(geo.p0.x() * (bb.b0 + bb.b1), 0.0);
        } else {
            A(1, 2) = bb.b0 + bb.b1;
            A(0, 3) = bb.b1;
            A(0, 4) = bb.b2;
            A(1, 5) = bb.b2;
            A(0, 6) = bb.b0 + bb.b1;
            c0 = geo.p3 * bb.b3;
        }
        // W = n n^T + w t t^T (distance_weights; W = I where the tangent is undefined or
        // w = 1): A^T W A and A^T W r as rank-one updates along n and t, the second skipped
        // at w = 0 (the default).
        V2 nor(1.0, 0.0);
        V2 tan(0.0, 1.0);
        double w = 1.0;
        if (tangent_weight < 1.0) {
            const V2 q1 = bezier_derivative(in ? ci : ce, t);
            if (q1.norm() > 1e-12) {
                tan = q1.normalized();
                nor = V2(-tan.y(), tan.x());
                w = tangent_weight;
            }
        }
        const V2 r = d[k] - c0;
        const VJ un = A.transpose() * nor;
        H.noalias() += un * un.transpose();
        g += un * nor.dot(r);
        if (w > 0.0) {
            const VJ ut = A.transpose() * tan;
            H.noalias() += w * ut * ut.transpose();
            g += ut * (w * tan.dot(r));
        }
    }
}

// One round from `cur`: step (a) (Eq. 7.9 for both segments at once, with the tangent weight of
// distance_weights), then step (b) (Eq. 7.10) on both segments.
JointState joint_round(std::span<const V2> d,
                       const JointGeometry& geo,
                       const JointState& cur,
                       double tangent_weight) {
    MJ H;
    VJ g;
    normal_equations(d, geo, cur, tangent_weight, H, g);
    CJ C;
    BJ b;
    joint_constraints(geo, C, b);
    // A pinned unknown is eliminated: its value moves to the right-hand sides, its row and
    // column leave the system, and H(i, i) = 1, g(i) = value return it unchanged.
    auto pin = [&](int i, double value) {
        g -= H.col(i) * value;
        b -= C.col(i) * value;
        H.row(i).setZero();
        H.col(i).setZero();
        C.col(i).setZero();
        H(i, i) = 1.0;
        g(i) = value;
    };
    if (!geo.free_rim) pin(6, geo.r_start);
    if (!geo.free_p0y) pin(7, geo.p0.y());
    JointState next;
    next.active = cur.active;
    next.q = minimise_joint_qp(H, g, C, b, cur.q, next.active);
    project_joint(d, geo, cur, next);
    return next;
}

// Covariance of (alpha, beta, r_rim, h_rim) at the converged state: s^2 Z (Z^T H Z)^-1 Z^T,
// H the Gauss-Newton matrix of the orthogonal residuals, Z spanning the directions the last
// round's active bounds (those pinned below) and the pinned unknowns leave free, s^2 = energy /
// (samples - free unknowns): the fit's own residual variance, so that it needs no noise model
// (NaN when the free block is singular). The handles' bounds (alpha, beta >= 0, alpha_ext >= 0,
// P0.x + alpha_ext <= P2.x <= P3.x) are not pinned even when active: under noise a fit rests on
// one of them (the exterior in most fits, an interior handle at 0 in some at 2 px), but which
// one, and whether at all, changes from realisation to realisation, so pinning its unknowns at
// this fit's bound understated the rim's spread (61 B-scans, 1 px: the per-half-line variance
// of r_rim over 100 realisations was 1.53x the covariance with the exterior's pinned, 1.16x
// without; docs/algorithms/cube.md "V_p: the plug-in volume's noise term", "Session 46").
Eigen::Matrix4d interior_covariance(std::span<const V2> d,
                                    const JointGeometry& geo,
                                    const JointState& cur) {
    MJ H;
    VJ g;
    normal_equations(d, geo, cur, 0.0, H, g);
    CJ C;
    BJ b;
    joint_constraints(geo, C, b);
    Eigen::MatrixXd A(0, kJoint);
    auto add_row = [&](const Eigen::Matrix<double, 1, kJoint>& r) {
        A.conservativeResize(A.rows() + 1, Eigen::NoChange);
        A.row(A.rows() - 1) = r;
    };
    for (int c = 0; c < kJointConstraints; ++c) {
        // The handles' bounds alpha, beta >= 0 (0-1) and the exterior's (3-5) are left free:
        // see above. Pinned when active: alpha + beta <= r_rim - P0.x (2; left free, the max
        // slope's term of a 25 x 128 phantom reached -754 deg on a half-line resting on it:
        // cube.md "Session 46") and the crest's bounds on r_rim (6-7).
        if (c <= 1 || (c >= 3 && c <= 5)) continue;
        if ((cur.active & (1U << c)) != 0U) add_row(C.row(c));
    }
    Eigen::Matrix<double, 1, kJoint> e = Eigen::Matrix<double, 1, kJoint>::Zero();
    if (!geo.free_rim) {
        e(6) = 1.0;
        add_row(e);
        e(6) = 0.0;
    }
    if (!geo.free_p0y) {
        e(7) = 1.0;
        add_row(e);
    }
    Eigen::MatrixXd Z;
    if (A.rows() == 0) {
        Z = Eigen::MatrixXd::Identity(kJoint, kJoint);
    } else {
        const Eigen::FullPivLU<Eigen::MatrixXd> lu(A);
        Z = lu.kernel();
    }
    Eigen::Matrix4d out = Eigen::Matrix4d::Constant(std::numeric_limits<double>::quiet_NaN());
    const auto num_free = Z.cols();
    const auto dof = static_cast<double>(d.size()) - static_cast<double>(num_free);
    if (num_free == 0 || dof <= 0.0) return out;
    const Eigen::MatrixXd red = Z.transpose() * H * Z;
    const Eigen::LDLT<Eigen::MatrixXd> ldlt(red);
    if (ldlt.info() != Eigen::Success) return out;
    const Eigen::MatrixXd cov = (cur.energy / dof) * (Z * ldlt.solve(Z.transpose()));
    const std::array<int, 4> ix{0, 1, 6, 2};
    for (int a = 0; a < 4; ++a) {
        for (int c = 0; c < 4; ++c) out(a, c) = cov(ix[a], ix[c]);
    }
    return out;
}

void require_samples(std::span<const V2> d, std::size_t min, const char* what) {
    if (d.size() < min) {
        throw AnalysisError(std::string(what) + ": needs at least " + std::to_string(min) +
                            " samples");
    }
}

// Start parameters on the curve c for the samples d (ordered by radius): interpolated in the
// curve's own x at the parameters t_fit of another sample set fitted to it (its foot points).
std::vector<double> start_parameters(std::span<const V2> d,
                                     const Ctrl& c,
                                     std::span<const double> t_fit) {
    std::vector<double> xs{c[0].x()};
    std::vector<double> ts{0.0};
    for (const double t : t_fit) {
        const double x = bezier_point(c, t).x();
        if (t > ts.back() && x > xs.back()) {
            xs.push_back(x);
            ts.push_back(t);
        }
    }
    if (ts.back() < 1.0 && c[3].x() > xs.back()) {
        xs.push_back(c[3].x());
        ts.push_back(1.0);
    }
    std::vector<double> t(d.size());
    for (std::size_t k = 0; k < d.size(); ++k) {
        const double x = d[k].x();
        const auto it = std::upper_bound(xs.begin(), xs.end(), x);
        if (it == xs.begin()) {
            t[k] = ts.front();
        } else if (it == xs.end()) {
            t[k] = ts.back();
        } else {
            const auto j = static_cast<std::size_t>(it - xs.begin());
            const double f = (x - xs[j - 1]) / (xs[j] - xs[j - 1]);
            t[k] = ts[j - 1] + f * (ts[j] - ts[j - 1]);
        }
    }
    return t;
}

// Sum of squared orthogonal distances of d to the curve c (foot points refined as the fit
// refines its own, from start_parameters).
double distances_to_curve(std::span<const V2> d, const Ctrl& c, std::span<const double> t_fit) {
    if (d.empty()) return 0.0;
    std::vector<double> t = start_parameters(d, c, t_fit);
    return update_foot_points(d, c, t, 0, d.size());
}

}  // namespace

namespace cube_detail {

double solve_x(const Ctrl& c, double x) {
    double lo = 0.0;
    double hi = 1.0;
    for (int it = 0; it < 200 && hi - lo > 0.0; ++it) {
        const double mid = 0.5 * (lo + hi);
        if (mid == lo || mid == hi) break;
        if (bezier_point(c, mid).x() < x) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    return 0.5 * (lo + hi);
}

void fit_half_line(CubeHalfLine& h,
                   double cft,
                   const CubeParams& p,
                   const FitSettings& fs,
                   const CubeHalfLine* start,
                   const BilinearSamples* bilinear) {
    // Valid samples; sample 0 is the centre (thickness CFT).
    std::vector<V2> pts;
    std::vector<int> idx;
    for (std::size_t k = 0; k < h.r_mm.size(); ++k) {
        if (std::isnan(h.h_mm[k])) continue;
        pts.emplace_back(h.r_mm[k], k == 0 ? cft : h.h_mm[k]);
        idx.push_back(static_cast<int>(k));
    }
    if (pts.size() < 6) {
        h.problem = "fewer than 6 valid samples";
        return;
    }
    std::size_t rim = 1;
    for (std::size_t k = 1; k < pts.size(); ++k) {
        if (pts[k].y() > pts[rim].y()) rim = k;  // first maximum (cube.md step 4)
    }
    if (rim < 2) {
        h.problem = "no pit: the maximum is next to the centre";
        return;
    }
    if (pts.size() - rim < 4) {
        h.problem = "no rim inside the radius: thickness still rising at its end";
        return;
    }
    if (bilinear == nullptr) {
        for (int k = 0; k < idx[rim]; ++k) {
            if (std::isnan(h.h_mm[static_cast<std::size_t>(k)])) ++h.num_missing_interior;
        }
    }
    // The rim height is the joint fit's estimate (docs/algorithms/cube.md "Rim point").
    RimProfileFit warm;
    const bool has_start = start != nullptr && start->valid;
    if (has_start) {
        warm.interior = start->interior;
        warm.exterior = start->exterior;
        if (warm.interior.t.size() + warm.exterior.t.size() != pts.size()) {
            // The start was fitted to other samples (the CFT pass's local fits): its foot points
            // on these — the samples up to its rim radius on its interior, the rest on its
            // exterior, whose end is the last sample (t = 1).
            const double split_x = warm.interior.control[3].x();
            std::size_t split = 0;
            while (split < pts.size() && pts[split].x() <= split_x) ++split;
            split = std::clamp<std::size_t>(split, 2, pts.size() - 2);
            const std::span<const V2> all(pts);
            const auto in = all.subspan(0, split);
            const auto ex = all.subspan(split);
            std::vector<double> ti = start_parameters(in, warm.interior.control, warm.interior.t);
            std::vector<double> te = start_parameters(ex, warm.exterior.control, warm.exterior.t);
            update_foot_points(in, warm.interior.control, ti, 1, in.size());
            update_foot_points(ex, warm.exterior.control, te, 0, ex.size() - 1);
            ti.front() = 0.0;
            te.back() = 1.0;
            warm.interior.t = std::move(ti);
            warm.exterior.t = std::move(te);
        }
    }
    RimProfileFit pf = fit_rim_profile(pts, static_cast<int>(rim), fs, has_start ? &warm : nullptr);
    if (fs.free_start_height) {  // CFT estimation pass: P0.y is used, the fit is a start
        h.interior = std::move(pf.interior);
        h.exterior = std::move(pf.exterior);
        h.valid = true;
        return;
    }
    h.interior = std::move(pf.interior);
    h.exterior = std::move(pf.exterior);
    h.interior_cov = pf.interior_cov;
    const Ctrl& qi = h.interior.control;
    half_line_parameters(h, p);
    double n = static_cast<double>(h.interior.num_samples + h.exterior.num_samples);
    double sse = h.interior.sse_mm2 + h.exterior.sse_mm2;
    if (bilinear != nullptr) {
        // The fit used sector bins: its RMSE is measured against the bilinear samples
        // (cube.md step 3) as before, i.e. the map's deviation from the model: each sample's
        // orthogonal distance to its segment (the interior up to the rim radius, the exterior
        // beyond it up to its end; the first sample is the centre at CFT). The bilinear samples
        // missing inside the rim are the pit's missing values.
        const Ctrl& ce = h.exterior.control;
        std::vector<V2> rin;
        std::vector<V2> rex;
        for (std::size_t k = 0; k < bilinear->r_mm.size(); ++k) {
            const double r = bilinear->r_mm[k];
            const double v = k == 0 ? cft : bilinear->h_mm[k];
            if (std::isnan(v)) {
                if (r < qi[3].x()) ++h.num_missing_interior;
                continue;
            }
            if (r <= qi[3].x()) {
                rin.emplace_back(r, v);
            } else if (r <= ce[3].x()) {
                rex.emplace_back(r, v);
            }
        }
        sse = distances_to_curve(rin, qi, h.interior.t) + distances_to_curve(rex, ce, h.exterior.t);
        n = static_cast<double>(rin.size() + rex.size());
    }
    h.rmse_sse_mm2 = sse;
    h.rmse_num_samples = static_cast<int>(n);
    h.rmse_um = 1000.0 * std::sqrt(sse / n);
    h.valid = true;
}

}  // namespace cube_detail

double bezier_t_at_x(const std::array<Eigen::Vector2d, 4>& p, double x) { return solve_x(p, x); }

double fitted_thickness_mm(const CubeHalfLine& h, double r_mm) {
    if (!h.valid || h.r_mm.empty() || r_mm < 0.0 || r_mm > h.r_mm.back()) return kMissing;
    for (const Ctrl* c : {&h.interior.control, &h.exterior.control}) {
        // Each segment is a graph in r (P0.x <= P3.x, Eq. 7.5-7.6).
        if (r_mm < (*c)[0].x() || r_mm > (*c)[3].x()) continue;
        return bezier_point(*c, solve_x(*c, r_mm)).y();
    }
    return kMissing;
}

V2 bezier_point(const Ctrl& p, double t) {
    const Bernstein b = bernstein(t);
    return b.b0 * p[0] + b.b1 * p[1] + b.b2 * p[2] + b.b3 * p[3];
}

V2 bezier_derivative(const Ctrl& p, double t) {
    const double s = 1.0 - t;
    return 3.0 * (s * s * (p[1] - p[0]) + 2.0 * s * t * (p[2] - p[1]) + t * t * (p[3] - p[2]));
}

BezierFit fit_interior(std::span<const V2> d, const FitSettings& s) {
    require_samples(d, 3, "interior fit");
    const V2 p0 = d.front();
    const V2 p3 = d.back();
    const double width = p3.x() - p0.x();
    if (!(width > 0.0)) throw AnalysisError("interior fit: the rim is not beyond the centre");
    // Eq. 7.7: Q = P0 (B0 + B1) + P3 (B2 + B3) + alpha T B1 - beta T B2 with T = (1, 0), linear
    // in (alpha, beta): Eq. 7.9 is a 2x2 linear least-squares problem.
    // With s.free_start_height, P0.y = c is a third unknown (Q.y gains c (B0 + B1)).
    const bool free_c = s.free_start_height;
    auto solve = [&](const std::vector<double>& t, const std::vector<Eigen::Matrix2d>& w) {
        Eigen::Matrix3d H = Eigen::Matrix3d::Zero();
        Eigen::Vector3d g = Eigen::Vector3d::Zero();
        for (std::size_t k = 0; k < d.size(); ++k) {
            const Bernstein b = bernstein(t[k]);
            const V2 base = free_c ? V2(p0.x(), 0.0) : p0;
            const V2 r = d[k] - base * (b.b0 + b.b1) - p3 * (b.b2 + b.b3);
            Eigen::Matrix<double, 2, 3> A;  // columns: dQ/dalpha, dQ/dbeta, dQ/dc
            A << b.b1, -b.b2, 0.0, 0.0, 0.0, free_c ? b.b0 + b.b1 : 0.0;
            H += A.transpose() * w[k] * A;
            g += A.transpose() * w[k] * r;
        }
        // Eliminate c (free), then 0 <= alpha, beta and alpha + beta <= w keep x(t) monotone
        // (the curve a graph).
        Eigen::Matrix2d Hr = H.topLeftCorner<2, 2>();
        V2 gr = g.head<2>();
        const bool has_c = free_c && H(2, 2) > 1e-300;
        if (has_c) {
            const V2 h = H.block<2, 1>(0, 2);
            Hr -= h * h.transpose() / H(2, 2);
            gr -= h * g(2) / H(2, 2);
        }
        const V2 z = minimise_on_triangle(Hr, gr, {V2(0.0, 0.0), V2(width, 0.0), V2(0.0, width)});
        const double c = has_c ? (g(2) - H(2, 0) * z.x() - H(2, 1) * z.y()) / H(2, 2) : p0.y();
        const V2 q0(p0.x(), c);
        return Ctrl{q0, q0 + V2(z.x(), 0.0), p3 - V2(z.y(), 0.0), p3};
    };
    return alternate(d, s, solve);
}

BezierFit fit_exterior(std::span<const V2> d, const FitSettings& s) {
    require_samples(d, 4, "exterior fit");
    const V2 p0 = d.front();
    const V2 p3 = d.back();
    if (!(p3.x() > p0.x())) throw AnalysisError("exterior fit: samples not ordered by radius");
    // Eq. 7.11: Q = P0 (B0 + B1) + alpha T B1 + P2 B2 + P3 B3, linear in (alpha, P2).
    auto solve = [&](const std::vector<double>& t, const std::vector<Eigen::Matrix2d>& w) {
        Eigen::Matrix3d H = Eigen::Matrix3d::Zero();
        Eigen::Vector3d g = Eigen::Vector3d::Zero();
        for (std::size_t k = 0; k < d.size(); ++k) {
            const Bernstein b = bernstein(t[k]);
            const V2 r = d[k] - p0 * (b.b0 + b.b1) - p3 * b.b3;
            Eigen::Matrix<double, 2, 3> A;  // columns: dQ/dalpha, dQ/dP2.x, dQ/dP2.y
            A << b.b1, b.b2, 0.0, 0.0, 0.0, b.b2;
            H += A.transpose() * w[k] * A;
            g += A.transpose() * w[k] * r;
        }
        // Eliminate P2.y (free), then the graph constraints on (alpha, P2.x):
        // 0 <= alpha, P0.x + alpha <= P2.x <= P3.x (a triangle).
        Eigen::Matrix2d Hr = H.topLeftCorner<2, 2>();
        V2 gr = g.head<2>();
        const bool has_y = H(2, 2) > 1e-300;
        if (has_y) {
            const V2 h = H.block<2, 1>(0, 2);
            Hr -= h * h.transpose() / H(2, 2);
            gr -= h * g(2) / H(2, 2);
        }
        const V2 z = minimise_on_triangle(
            Hr, gr, {V2(0.0, p0.x()), V2(0.0, p3.x()), V2(p3.x() - p0.x(), p3.x())});
        const double p2y =
            has_y ? (g(2) - H(2, 0) * z.x() - H(2, 1) * z.y()) / H(2, 2) : 0.5 * (p0.y() + p3.y());
        return Ctrl{p0, p0 + V2(z.x(), 0.0), V2(z.y(), p2y), p3};
    };
    return alternate(d, s, solve);
}

// Successive steps of the joint rounds this close in direction (cosine) are a creep.
constexpr double kCreepCosine = 0.95;

RimProfileFit fit_rim_profile(std::span<const V2> d,
                              int rim_index,
                              const FitSettings& s,
                              const RimProfileFit* start) {
    const auto n = d.size();
    const auto r0 = static_cast<std::size_t>(std::max(rim_index, 0));
    if (rim_index < 2 || n < r0 + 4) {
        throw AnalysisError("rim profile fit: the rim needs 2 samples before it and 3 after");
    }
    RimProfileFit out;
    // The crest (RimPoint::kCrest): the samples within crest_tolerance_mm of the maximum one,
    // widened by half a step (the maximum lies between samples), inside [third, fourth-last].
    double r_lo = d[r0].x();
    double r_hi = d[r0].x();
    for (std::size_t k = 1; k < n; ++k) {
        if (d[k].y() < d[r0].y() - s.crest_tolerance_mm) continue;
        r_lo = std::min(r_lo, d[k].x());
        r_hi = std::max(r_hi, d[k].x());
    }
    r_lo = std::max(d[2].x(), r_lo - 0.5 * (d[r0].x() - d[r0 - 1].x()));
    r_hi = std::min(d[n - 4].x(), r_hi + 0.5 * (d[r0 + 1].x() - d[r0].x()));
    const JointGeometry geo{
        d.front(),          d.back(), r_lo, r_hi, d[r0].x(), s.rim_point == RimPoint::kCrest,
        s.free_start_height};
    JointState cur;
    if (start != nullptr && start->interior.t.size() + start->exterior.t.size() == n) {
        const Ctrl& ci = start->interior.control;
        const Ctrl& ce = start->exterior.control;
        cur.q << ci[1].x() - ci[0].x(), ci[3].x() - ci[2].x(), ci[3].y(), ce[1].x() - ce[0].x(),
            ce[2].x(), ce[2].y(), ci[3].x(), d.front().y();
        cur.split = start->interior.t.size();
        cur.t = start->interior.t;
        cur.t.insert(cur.t.end(), start->exterior.t.begin(), start->exterior.t.end());
    } else {
        // Start (cube.md step 5, "Rim point"): both segments through the rim sample.
        FitSettings fixed = s;
        fixed.free_start_height = false;
        const BezierFit fi = fit_interior(d.subspan(0, r0 + 1), fixed);
        const BezierFit fe = fit_exterior(d.subspan(r0), fixed);
        cur.q << fi.control[1].x() - fi.control[0].x(), fi.control[3].x() - fi.control[2].x(),
            d[r0].y(), fe.control[1].x() - fe.control[0].x(), fe.control[2].x(), fe.control[2].y(),
            d[r0].x(), d.front().y();
        cur.split = r0 + 1;  // the rim sample is the interior's last (t free)
        cur.t = fi.t;
        cur.t.insert(cur.t.end(), fe.t.begin() + 1, fe.t.end());
    }
    if (geo.free_rim && (cur.q(6) < r_lo || cur.q(6) > r_hi)) {
        // A start fitted to other samples may put its rim outside this crest: the nearest end
        // of the crest, the other unknowns moved into the graph constraints (the rounds need a
        // feasible start).
        cur.q(6) = std::clamp(cur.q(6), r_lo, r_hi);
        const double w = cur.q(6) - geo.p0.x();
        cur.q(1) = std::clamp(cur.q(1), 0.0, w);
        cur.q(0) = std::clamp(cur.q(0), 0.0, w - cur.q(1));
        cur.q(3) = std::clamp(cur.q(3), 0.0, geo.p3.x() - cur.q(6));
        cur.q(4) = std::clamp(cur.q(4), cur.q(6) + cur.q(3), geo.p3.x());
    }
    cur.energy = joint_energy(d, geo, cur);
    VJ last_step = VJ::Zero();
    CJ C;  // the graph constraints, for the creep's doubled steps
    BJ b;
    joint_constraints(geo, C, b);
    for (int round = 1; round <= s.max_rounds; ++round) {
        out.rounds = round;
        if (cur.energy <= 1e-30) {
            out.converged = true;
            break;
        }
        JointState next = joint_round(d, geo, cur, kTangentWeight);
        // The tangent-distance step is a Gauss-Newton step on the energy with the foot points
        // eliminated; where the full step overshoots, shorter steps along it (the segment
        // from a feasible q to a feasible q stays feasible) usually still descend.
        for (double f = 0.5; next.energy > cur.energy && f >= 1.0 / 64.0; f *= 0.5) {
            JointState shorter;
            shorter.active = next.active;
            shorter.q = cur.q + f * (next.q - cur.q);
            project_joint(d, geo, cur, shorter);
            if (shorter.energy <= cur.energy) next = std::move(shorter);
        }
        // A step that reverses the previous one is the zig-zag of a flat valley (the rim on a
        // flat crest): the valley floor lies between the two points, so try the midpoint too.
        if (next.energy <= cur.energy && last_step.dot(next.q - cur.q) < 0.0) {
            JointState mid;
            mid.active = next.active;
            mid.q = cur.q + 0.5 * (next.q - cur.q);
            project_joint(d, geo, cur, mid);
            if (mid.energy < next.energy) next = std::move(mid);
        }
        if (next.energy > cur.energy) next = joint_round(d, geo, cur, 1.0);
        // A step along the previous one is the slow creep of a flat valley (under noise most
        // often the exterior's handles, which the data hardly fix, drifting toward a bound by
        // ~1e-6 mm a round): doubled steps along it, while they stay inside the graph
        // constraints and lower the energy further, cover that creep in a few rounds instead of
        // running into max_rounds.
        if (next.energy <= cur.energy && last_step.squaredNorm() > 0.0) {
            const VJ dq = next.q - cur.q;
            const double norms = dq.norm() * last_step.norm();
            if (norms > 0.0 && dq.dot(last_step) > kCreepCosine * norms) {
                for (double f = 2.0; f <= 64.0; f *= 2.0) {
                    JointState far;
                    far.active = next.active;
                    far.q = cur.q + f * dq;
                    if (!((C * far.q - b).array() <= 0.0).all()) break;
                    project_joint(d, geo, cur, far);
                    if (!(far.energy < next.energy)) break;
                    next = std::move(far);
                }
            }
        }
        if (next.energy > cur.energy) {  // no step lowers the energy: at the minimum
            out.converged = true;
            break;
        }
        const double prev = cur.energy;
        const double step = (next.q - cur.q).cwiseAbs().maxCoeff();
        last_step = next.q - cur.q;
        cur = std::move(next);
        // Converged: the energy (cube.md step 5) or every control point has stopped moving (below
        // 1e-7 mm = 0.1 nm a round: the linear tail of a zig-zag changes no output).
        if (std::fabs(prev - cur.energy) <= s.energy_tolerance * prev || step < 1e-7) {
            out.converged = true;
            break;
        }
    }
    auto segment = [&](const Ctrl& c, std::size_t first, std::size_t last) {
        BezierFit f;
        f.control = c;
        f.t.assign(cur.t.begin() + static_cast<std::ptrdiff_t>(first),
                   cur.t.begin() + static_cast<std::ptrdiff_t>(last));
        for (std::size_t k = first; k < last; ++k) {
            f.sse_mm2 += (d[k] - bezier_point(c, cur.t[k])).squaredNorm();
        }
        f.num_samples = static_cast<int>(last - first);
        f.rounds = out.rounds;
        f.converged = out.converged;
        return f;
    };
    out.interior = segment(joint_interior(cur.q, geo), 0, cur.split);
    out.exterior = segment(joint_exterior(cur.q, geo), cur.split, n);
    out.rim = V2(cur.q(6), cur.q(2));
    if (s.covariance) out.interior_cov = interior_covariance(d, geo, cur);
    return out;
}

MaxSlope interior_max_slope(const Ctrl& q) {
    // x'(t) = 3[alpha (1-t)^2 + 2 (w - alpha - beta) t (1-t) + beta t^2], y'(t) = 6 dy t (1-t):
    // with u = t/(1-t), 1/s = [alpha/u + beta u + 2 (w - alpha - beta)] / (2 dy), smallest at
    // u = sqrt(alpha/beta) where alpha/u + beta u = 2 sqrt(alpha beta).
    const double w = q[3].x() - q[0].x();
    const double dy = q[3].y() - q[0].y();
    const double alpha = std::max(0.0, q[1].x() - q[0].x());
    const double beta = std::max(0.0, q[3].x() - q[2].x());
    MaxSlope m;
    const double sa = std::sqrt(alpha);
    const double sb = std::sqrt(beta);
    m.t = sa + sb > 0.0 ? sa / (sa + sb) : 0.5;
    const double den = std::sqrt(alpha * beta) + w - alpha - beta;
    m.slope = den > 0.0 ? dy / den : std::numeric_limits<double>::infinity();
    return m;
}

double bezier_volume_integral(const Ctrl& p, double t1) {
    // 5-point Gauss-Legendre is exact to degree 9; y x x' has degree 3 + 3 + 2 = 8.
    static constexpr std::array<double, 5> kX{0.0, -0.5384693101056831, 0.5384693101056831,
                                              -0.9061798459386640, 0.9061798459386640};
    static constexpr std::array<double, 5> kW{0.5688888888888889, 0.4786286704993665,
                                              0.4786286704993665, 0.2369268850561891,
                                              0.2369268850561891};
    double sum = 0.0;
    for (std::size_t i = 0; i < 5; ++i) {
        const double t = 0.5 * t1 * (kX[i] + 1.0);
        const V2 q = bezier_point(p, t);
        sum += kW[i] * q.y() * q.x() * bezier_derivative(p, t).x();
    }
    return 0.5 * t1 * sum;
}

}  // namespace octshape::retina
