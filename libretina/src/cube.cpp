// CuBe fovea analysis (thesis §7.1-7.3, SPEC §4). Decisions: docs/algorithms/cube.md.

#include "octshape/retina/cube.h"

#include <Eigen/Dense>
#include <algorithm>
#include <bit>
#include <cmath>
#include <numbers>
#include <optional>
#include <string>

#include "octshape/io/error.h"
#include "octshape/retina/scan_geometry.h"

namespace octshape::retina {
namespace {

using V2 = Eigen::Vector2d;
using V3 = Eigen::Vector3d;
using Ctrl = std::array<V2, 4>;

constexpr double kPi = std::numbers::pi;
constexpr double kDeg = 180.0 / kPi;

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
        // Converged: the energy (SPEC §4.5), or no control point moves by 1e-7 mm (0.1 nm).
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
// h_rim), P2_ext, P3. r_rim is pinned to the maximum sample (RimPoint::kMaximum, SPEC §4.4) or
// free (kFit); P0.y is free only in the CFT pass and otherwise pinned to the shared CFT.
constexpr int kJoint = 8;
constexpr int kJointConstraints = 8;
using VJ = Eigen::Matrix<double, kJoint, 1>;
using MJ = Eigen::Matrix<double, kJoint, kJoint>;
using CJ = Eigen::Matrix<double, kJointConstraints, kJoint>;
using BJ = Eigen::Matrix<double, kJointConstraints, 1>;
using Kkt = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, kJoint + kJointConstraints,
                          kJoint + kJointConstraints>;
using KktVec = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, kJoint + kJointConstraints, 1>;

struct JointGeometry {
    V2 p0;         // interior P0 = (0, CFT)
    V2 p3;         // exterior P3 = the last sample
    double r_min;    // bounds of a free rim radius q(6): the third and the fourth-last sample
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
VJ minimise_joint_qp(const MJ& H,
                     const VJ& g,
                     const CJ& C,
                     const BJ& b,
                     const VJ& fallback,
                     unsigned& mask) {
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
void project_joint(std::span<const V2> d, const JointGeometry& geo, const JointState& cur,
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

// One round from `cur`: step (a) (Eq. 7.9 for both segments at once, with the tangent weight of
// distance_weights), then step (b) (Eq. 7.10) on both segments.
JointState joint_round(std::span<const V2> d, const JointGeometry& geo, const JointState& cur,
                       double tangent_weight) {
    const std::size_t n = d.size();
    const std::size_t split = cur.split;
    const Ctrl ci = joint_interior(cur.q, geo);
    const Ctrl ce = joint_exterior(cur.q, geo);
    MJ H = MJ::Zero();
    VJ g = VJ::Zero();
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

void require_samples(std::span<const V2> d, std::size_t min, const char* what) {
    if (d.size() < min) {
        throw AnalysisError(std::string(what) + ": needs at least " + std::to_string(min) +
                            " samples");
    }
}

double median(std::vector<double> v) {
    std::sort(v.begin(), v.end());
    const std::size_t n = v.size();
    return n % 2 == 1 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

// Covariance eigen-analysis, shoelace area and opposite-point diameter (Eq. 7.16-7.18).
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

// x(t) = x on a curve whose x is monotone: bisection to the last bit.
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

// Vertex of the least-squares quadratic surface fitted to the valid nodes of M within the window
// |x - c.x| <= rx, |y - c.y| <= ry (a parabola in x for a line scan); nullopt when the fit is not
// a bowl or its vertex leaves the window. `value`, when given, receives the surface's height at
// the vertex (2-D fits only; the analysis uses it as the centre sample under noise).
std::optional<V2> quadratic_vertex(const ThicknessMap& m,
                                   const V2& c,
                                   double rx,
                                   double ry,
                                   double* value = nullptr) {
    const bool line = m.rows == 1;
    const int a0 = std::max(0, static_cast<int>(std::floor((c.x() - rx) / m.dx_mm)));
    const int a1 = std::min(m.cols - 1, static_cast<int>(std::ceil((c.x() + rx) / m.dx_mm)));
    int b0 = 0;
    int b1 = 0;
    if (!line) {
        b0 = std::max(0, static_cast<int>(std::floor((c.y() - ry) / m.dy_mm)));
        b1 = std::min(m.rows - 1, static_cast<int>(std::ceil((c.y() + ry) / m.dy_mm)));
    }
    Eigen::Matrix<double, 6, 6> N = Eigen::Matrix<double, 6, 6>::Zero();
    Eigen::Matrix<double, 6, 1> rhs = Eigen::Matrix<double, 6, 1>::Zero();
    int count = 0;
    for (int b = b0; b <= b1; ++b) {
        for (int a = a0; a <= a1; ++a) {
            const double v = m.at(b, a);
            if (std::isnan(v)) continue;
            const double u = a * m.dx_mm - c.x();
            const double w = line ? 0.0 : b * m.dy_mm - c.y();
            if (std::fabs(u) > rx + 1e-12 || std::fabs(w) > ry + 1e-12) continue;
            Eigen::Matrix<double, 6, 1> phi;
            phi << 1.0, u, w, u * u, u * w, w * w;
            N += phi * phi.transpose();
            rhs += phi * v;
            ++count;
        }
    }
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
double noisy_centre_fit_radius_mm(double sd_mm) {
    return kNoisyCentreFitRadiusMm * std::cbrt(sd_mm / kOnePixelNoiseMm);
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
// Samples that are missing under SPEC §4.3 (a missing bilinear neighbour) stay missing.
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

// With `sector_nodes` (size n), also hands every valid node within `sector_radius` of the centre
// to its own sector's list as (radius, thickness): the sector bins of the final fit.
void local_fit_samples(const ThicknessMap& m,
                       const V2& c,
                       const Eigen::Matrix2d& grid_to_anatomical,
                       const LocalFitWindow& win,
                       std::vector<CubeHalfLine>& lines,
                       std::vector<std::vector<V2>>* sector_nodes = nullptr,
                       double sector_radius = 0.0) {
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
    using V4 = Eigen::Vector4d;
    using M4 = Eigen::Matrix4d;
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
                w >= r ? quarter
                       : std::min(quarter,
                                  static_cast<long>(std::ceil(std::asin(w / r) / step)) + 1);
            for (long j = i0 - reach; j <= i0 + reach; ++j) {
                const auto i = static_cast<std::size_t>(((j % static_cast<long>(n)) +
                                                         static_cast<long>(n)) %
                                                        static_cast<long>(n));
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
            const LocalFitSums& q = sums[i * ns + k];
            if (std::isnan(lines[i].h_mm[k]) || q.count < win.min_nodes) continue;
            const Eigen::LDLT<M4> ldlt(q.normal());
            const auto d = ldlt.vectorD();
            if (ldlt.info() != Eigen::Success || !(d.minCoeff() > 1e-9 * d.maxCoeff())) continue;
            // Noise of the fit's value: sigma^2 (N^-1)_00; the bilinear sample's: sigma^2 sum w^2
            // of its 4 weights. Keep the less noisy (a window whose nodes barely span rho or
            // tau extrapolates).
            const double var_fit = ldlt.solve(V4::UnitX())(0);
            const V2 g = c + radii[k] * dir[i];
            const double u = g.x() / m.dx_mm - std::floor(g.x() / m.dx_mm);
            const double t = g.y() / m.dy_mm - std::floor(g.y() / m.dy_mm);
            const double var_bilinear =
                ((1.0 - u) * (1.0 - u) + u * u) * ((1.0 - t) * (1.0 - t) + t * t);
            if (!(var_fit < var_bilinear)) continue;
            const V4 z = ldlt.solve(q.rhs());
            if (std::isfinite(z(0))) lines[i].h_mm[k] = z(0);
        }
    }
}

// ---- the final fit's samples under noise: sector bins (docs/algorithms/cube.md "Radial
// samples under noise") -------------------------------------------------------------------------
// Every valid node p with 0 < |p - c| <= R belongs to the half-line nearest to its anatomical
// angle (sectors of +-180 deg / n: they tile the disk, every node serves exactly one half-line;
// local_fit_samples hands them over). A half-line's nodes, ordered by radius, are cut into runs of k consecutive nodes, k =
// round(count / K) >= 1 with K the number of regular samples of a half-line, and each run is one
// sample: the mean thickness of its nodes at the root-mean-square radius of its nodes. Equal
// runs give every sample the same noise (sigma^2 / k), so the unweighted fit weighs them alike;
// no node serves twice and nothing is smoothed across the radius. The RMS radius makes a run's
// mean exact for T = a + b r^2 (the pit floor, where a sector is narrow and a run spans up to
// ~0.15 mm: the mean radius would put the mean ~1 um too high there); where a run spans a few
// um, as elsewhere, the two radii differ by < 0.02 um. The last run takes the remainder (k to
// 2k - 1 nodes). A half-line with fewer than kMinSectorNodes nodes keeps its samples. Sample 0
// stays the centre.
constexpr std::size_t kMinSectorNodes = 16;

void sector_bin_samples(std::vector<std::vector<V2>>& nodes, std::vector<CubeHalfLine>& lines) {
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
            1, static_cast<std::size_t>(std::lround(static_cast<double>(d.size()) /
                                                    static_cast<double>(regular))));
        const std::size_t runs = d.size() / k;
        CubeHalfLine& h = lines[i];
        h.r_mm.resize(1);
        h.h_mm.resize(1);
        for (std::size_t j = 0; j < runs; ++j) {
            const std::size_t first = j * k;
            const std::size_t last = j + 1 == runs ? d.size() : first + k;
            double sum_h = 0.0;
            double sum_r2 = 0.0;
            for (std::size_t q = first; q < last; ++q) {
                sum_h += d[q].y();
                sum_r2 += d[q].x() * d[q].x();
            }
            const auto count = static_cast<double>(last - first);
            h.r_mm.push_back(std::sqrt(sum_r2 / count));
            h.h_mm.push_back(sum_h / count);
        }
    }
}

// The bilinear samples of a half-line at the regular radii (SPEC §4.3), kept beside the sector
// bins for the RMSE and the count of missing values in the pit.
struct BilinearSamples {
    const std::vector<double>& r_mm;
    const std::vector<double>& h_mm;
};

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

void fit_half_line(CubeHalfLine& h,
                   double cft,
                   const CubeParams& p,
                   const FitSettings& fs,
                   const CubeHalfLine* start = nullptr,
                   const BilinearSamples* bilinear = nullptr) {
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
        if (pts[k].y() > pts[rim].y()) rim = k;  // first maximum (SPEC §4.4)
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
    double n = static_cast<double>(h.interior.num_samples + h.exterior.num_samples);
    double sse = h.interior.sse_mm2 + h.exterior.sse_mm2;
    if (bilinear != nullptr) {
        // The fit used sector bins: its RMSE is measured against the bilinear samples (SPEC
        // §4.3) as before, i.e. the map's deviation from the model: each sample's orthogonal
        // distance to its segment (the interior up to the rim radius, the exterior beyond it up
        // to its end; the first sample is the centre at CFT). The bilinear samples missing
        // inside the rim are the pit's missing values.
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
        sse = distances_to_curve(rin, qi, h.interior.t) +
              distances_to_curve(rex, ce, h.exterior.t);
        n = static_cast<double>(rin.size() + rex.size());
    }
    h.rmse_um = 1000.0 * std::sqrt(sse / n);
    h.valid = true;
}

bool is_volume(const io::Scan& scan) {
    const auto pat = scan.meta.pattern;
    return pat == io::ScanPattern::kVolume || pat == io::ScanPattern::kFastVolume ||
           (pat == io::ScanPattern::kUnknown && scan.num_bscans() > 1);
}

}  // namespace

CubeDisk cube_disk(std::vector<Eigen::Vector3d> points) { return disk(std::move(points)); }

double bezier_t_at_x(const std::array<Eigen::Vector2d, 4>& p, double x) { return solve_x(p, x); }

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
    // SPEC §4.3: a sample whose four neighbours are not all valid is missing.
    if (std::isnan(m00) || std::isnan(m01) || std::isnan(m10) || std::isnan(m11)) return kMissing;
    return (1.0 - v) * ((1.0 - u) * m00 + u * m01) + v * ((1.0 - u) * m10 + u * m11);
}

ThicknessMap thickness_map(const io::Scan& scan) {
    ThicknessMap m;
    m.rows = scan.num_bscans();
    m.cols = scan.meta.size_x;
    m.dx_mm = scan.meta.scale_x_mm;
    m.dy_mm = m.rows > 1 ? scan.meta.distance_mm : 0.0;
    if (m.rows < 1 || m.cols < 2) throw AnalysisError("the scan holds no B-scans to analyse");
    const int ilm = static_cast<int>(io::Layer::kILM);
    const int bm = static_cast<int>(io::Layer::kBM);
    if (scan.num_lines() <= bm) {
        throw AnalysisError("the export has no ILM and BM segmentation (needed for thickness)");
    }
    if (scan.valid_fraction(bm) == 0.0) {
        throw AnalysisError("the BM segmentation is missing everywhere (needed for thickness)");
    }
    if (scan.valid_fraction(ilm) == 0.0) {
        throw AnalysisError("the ILM segmentation is missing everywhere (needed for thickness)");
    }
    const double sz = scan.meta.scale_z_mm;
    m.mm.assign(static_cast<std::size_t>(m.rows) * static_cast<std::size_t>(m.cols), kMissing);
    for (int b = 0; b < m.rows; ++b) {
        const auto& bs = scan.bscans[static_cast<std::size_t>(b)];
        for (int a = 0; a < m.cols; ++a) {
            const auto i = static_cast<std::size_t>(a);
            const float di = i < bs.seg[0].size() ? bs.seg[0][i] : io::kNoPixelData;
            const float db = i < bs.seg[1].size() ? bs.seg[1][i] : io::kNoPixelData;
            double v = kMissing;
            // Height z = -depth * ScaleZ, so ILM - BM = (depth_BM - depth_ILM) * ScaleZ.
            if (io::is_valid(di) && io::is_valid(db) && di < io::kInvalidThreshold &&
                db < io::kInvalidThreshold) {
                v = (static_cast<double>(db) - static_cast<double>(di)) * sz;
            }
            if (std::isnan(v)) ++m.num_missing;
            m.mm[static_cast<std::size_t>(b) * static_cast<std::size_t>(m.cols) + i] = v;
        }
    }
    return m;
}

std::string_view to_string(RimPoint r) { return r == RimPoint::kCrest ? "crest" : "maximum"; }

RimPoint parse_rim_point(std::string_view s) {
    if (s == "crest") return RimPoint::kCrest;
    if (s == "maximum") return RimPoint::kMaximum;
    throw UsageError("rim point '" + std::string(s) + "': expected crest or maximum");
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

void CubeParams::validate() const {
    auto bad = [](const std::string& field, const std::string& why) {
        throw UsageError("macula parameter " + field + ": " + why);
    };
    if (num_half_lines < 4 || num_half_lines % 2 != 0 || num_half_lines > 3600) {
        bad("num_half_lines", "must be even and in 4..3600");
    }
    if (!(radius_mm > 0.0) || radius_mm > 10.0) bad("radius_mm", "must be in (0, 10] mm");
    if (!(sample_spacing_mm >= 0.0) || sample_spacing_mm > radius_mm / 8.0) {
        bad("sample_spacing_mm", "must be 0 (ScaleX) or in (0, radius/8]");
    }
    if (!(tau_mm > 0.0) || tau_mm > 0.2) bad("tau_mm", "must be in (0, 0.2] mm");
    if (!(inner_radius_mm > 0.0) || inner_radius_mm >= radius_mm) {
        bad("inner_radius_mm", "must be in (0, radius)");
    }
    if (!(search_radius_mm >= 0.0) || search_radius_mm > 5.0) {
        bad("search_radius_mm", "must be in [0, 5] mm");
    }
    if (!(tie_tolerance_mm >= 0.0) || tie_tolerance_mm > 0.01) {
        bad("tie_tolerance_mm", "must be in [0, 0.01] mm");
    }
    if (!(centre_smoothing_mm >= 0.0) || centre_smoothing_mm > 0.5) {
        bad("centre_smoothing_mm", "must be in [0, 0.5] mm");
    }
    if (!(centre_fit_radius_mm >= 0.0) || centre_fit_radius_mm > 0.5) {
        bad("centre_fit_radius_mm", "must be in [0, 0.5] mm");
    }
    if (max_rounds < 1 || max_rounds > 100000) bad("max_rounds", "must be in 1..100000");
    if (!(energy_tolerance > 0.0) || energy_tolerance >= 1.0) {
        bad("energy_tolerance", "must be in (0, 1)");
    }
    if (!(rmse_warning_um > 0.0)) bad("rmse_warning_um", "must be > 0");
    if (!(local_fit_min_noise_um >= 0.0)) {
        bad("local_fit_min_noise_um", "must be >= 0 (+inf: always bilinear)");
    }
    if (centre_mm && !centre_mm->allFinite()) bad("centre_mm", "must be finite");
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
    const JointGeometry geo{d.front(), d.back(), r_lo, r_hi, d[r0].x(),
                            s.rim_point == RimPoint::kCrest, s.free_start_height};
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
        // Start (SPEC §4.4-4.5): both segments through the rim sample.
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
        // Converged: the energy (SPEC §4.5) or every control point has stopped moving (below
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

CubeResult analyse_macula(const io::Scan& scan, const CubeParams& params) {
    params.validate();
    CubeResult res;
    const auto pat = scan.meta.pattern;
    if (pat == io::ScanPattern::kLine) {
        if (scan.num_bscans() != 1) {
            throw AnalysisError("line scan with " + std::to_string(scan.num_bscans()) +
                                " B-scans: expected exactly one B-scan through the fovea");
        }
        res.line_scan = true;
    } else if (!is_volume(scan)) {
        throw AnalysisError("scan pattern '" + std::string(io::to_string(pat)) +
                            "' cannot be analysed as a macula: a volume scan or a single line "
                            "through the fovea is needed");
    }
    if (!res.line_scan && !(scan.meta.distance_mm > 0.0)) {
        throw AnalysisError("volume scan without a B-scan distance in its header");
    }
    if (!(scan.meta.scale_x_mm > 0.0) || !(scan.meta.scale_z_mm > 0.0)) {
        throw AnalysisError("the scan's ScaleX/ScaleZ are not positive");
    }
    res.map = thickness_map(scan);
    const double noise_sd_mm = thickness_noise_sd(res.map);
    res.thickness_noise_sd_um = noise_sd_mm * 1e3;
    // 3 SDs: a sample that low below the maximum one is its rival only if the two noises differ
    // by > 3 / sqrt(2) = 2.1 SDs, which happens to ~2 % of pairs.
    const double crest_mm = 3.0 * noise_sd_mm;
    // Segmentation noise worth a noise-adaptive estimator (centre window, radial samples).
    const bool noisy = !res.line_scan &&
                       res.thickness_noise_sd_um >= params.local_fit_min_noise_um;
    const ThicknessMap& m = res.map;
    const ScanGeometry geo(scan);
    // Under noise, the centre sample of the CFT pass: the height of the centre's quadratic
    // surface at its vertex (docs/algorithms/cube.md "Centre sample under noise"); NaN = M at
    // the centre (bilinear, SPEC §4.3).
    double centre_sample_mm = kMissing;
    const double width = (m.cols - 1) * m.dx_mm;
    const double height = (m.rows - 1) * m.dy_mm;

    // ---- centre (SPEC §4.2, Eq. 7.13) --------------------------------------------------------
    res.search_centre_mm = V2(0.5 * width, 0.5 * height);
    res.centre_source = "scan centre";
    if (!res.line_scan && !scan.grids.empty()) {
        const auto& g = scan.grids.front();
        const V2 c = geo.slo_to_grid(V2(g.centre_x_slo_mm, g.centre_y_slo_mm));
        if (c.allFinite() && c.x() >= 0.0 && c.x() <= width && c.y() >= 0.0 && c.y() <= height) {
            res.search_centre_mm = c;
            res.centre_source = "device thickness grid";
        } else {
            res.notes.push_back(
                "the device grid centre lies outside the scan: searched around "
                "the scan centre");
        }
    }
    if (params.centre_mm) {
        res.centre_mm = *params.centre_mm;
        res.centre_source = "given";
        res.cft_mm = m.sample(res.centre_mm.x(), res.centre_mm.y());
        res.num_tied_minima = 0;
        if (std::isnan(res.cft_mm)) throw AnalysisError("no valid thickness at the given centre");
    } else {
        const double rs = params.search_radius_mm;
        // The node box around the search circle; values: M smoothed for the search (SPEC §4.2
        // on the smoothed map; docs/algorithms/cube.md "Centre").
        const V2& sc = res.search_centre_mm;
        NodeBox bx;
        bx.a0 = std::clamp(static_cast<int>(std::floor((sc.x() - rs) / m.dx_mm)), 0, m.cols - 1);
        bx.a1 = std::clamp(static_cast<int>(std::ceil((sc.x() + rs) / m.dx_mm)), 0, m.cols - 1);
        if (m.rows > 1) {
            bx.b0 = std::clamp(static_cast<int>(std::floor((sc.y() - rs) / m.dy_mm)), 0, m.rows - 1);
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
        res.num_tied_minima = static_cast<int>(xs.size());
        const V2 node_centre(median(xs), median(ys));  // Eq. 7.13, component-wise median
        res.centre_mm = node_centre;
        if (params.centre_fit_radius_mm > 0.0) {
            // Between the nodes: the vertex of a quadratic fitted to M around the minimum (the
            // window spans at least the neighbouring B-scans). Under noise the window widens
            // with sigma^(1/3) (docs/algorithms/cube.md "Radial samples under noise").
            double fit_r = params.centre_fit_radius_mm;
            if (noisy) fit_r = std::max(fit_r, noisy_centre_fit_radius_mm(noise_sd_mm));
            res.centre_fit_radius_mm = fit_r;
            const double rx = std::max(fit_r, 1.01 * m.dx_mm);
            const double ry = std::max(fit_r, 1.01 * m.dy_mm);
            double vertex_mm = kMissing;
            if (const auto v = quadratic_vertex(m, res.centre_mm, rx, ry, &vertex_mm)) {
                res.centre_mm = *v;
                if (noisy) centre_sample_mm = vertex_mm;
            }
        }
        double cv = m.sample(res.centre_mm.x(), res.centre_mm.y());
        if (std::isnan(cv) && res.centre_mm != node_centre) {
            // Missing values next to the refined centre: keep the minimum's node centre.
            res.centre_mm = node_centre;
            centre_sample_mm = kMissing;
            cv = m.sample(node_centre.x(), node_centre.y());
            res.notes.push_back("missing thickness next to the refined centre: the centre is the "
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
                    res.centre_mm = V2(xs[k], ys[k]);
                    cv = raw;
                }
            }
            if (std::isnan(cv)) throw AnalysisError("no valid thickness at the centre found");
            res.notes.push_back("missing thickness around the minimum: CFT is the value of the "
                                "nearest valid minimum node");
        }
        res.cft_mm = cv;
        const double step = std::max(m.dx_mm, m.dy_mm);
        if ((res.centre_mm - res.search_centre_mm).norm() > rs - step) {
            res.qc_flags.push_back("centre at search border");
        }
    }

    // ---- radial half-lines (SPEC §4.3) -------------------------------------------------------
    const double spacing =
        params.sample_spacing_mm > 0.0 ? params.sample_spacing_mm : scan.meta.scale_x_mm;
    res.sample_spacing_mm = spacing;
    std::vector<double> radii;
    const int K = static_cast<int>(std::floor(params.radius_mm / spacing + 1e-9));
    for (int k = 0; k <= K; ++k) radii.push_back(k * spacing);
    if (params.radius_mm - K * spacing > 1e-9) radii.push_back(params.radius_mm);

    const int n = res.line_scan ? 2 : params.num_half_lines;
    const Eigen::Matrix2d to_grid = geo.grid_to_anatomical().inverse();
    for (int i = 0; i < n; ++i) {
        CubeHalfLine h;
        h.angle_deg = 360.0 * i / n;
        const double th = h.angle_deg / kDeg;
        if (res.line_scan) {
            // Nasal (0 deg) is along grid +x when the line's +x points nasally.
            const double sx = geo.x_is_nasal() ? 1.0 : -1.0;
            h.direction = V2(i == 0 ? sx : -sx, 0.0);
        } else {
            h.direction = (to_grid * V2(std::cos(th), std::sin(th))).normalized();
        }
        h.r_mm = radii;
        h.h_mm.resize(radii.size());
        for (std::size_t k = 0; k < radii.size(); ++k) {
            const V2 q = res.centre_mm + radii[k] * h.direction;
            h.h_mm[k] = k == 0 ? res.cft_mm : m.sample(q.x(), res.line_scan ? 0.0 : q.y());
            if (std::isnan(h.h_mm[k])) ++h.num_missing;
        }
        res.half_lines.push_back(std::move(h));
    }
    // Under segmentation noise the samples are local fits over every node of their sector
    // (docs/algorithms/cube.md "Radial samples under noise"); the bilinear ones are kept for
    // the RMSE.
    std::vector<std::vector<double>> bilinear;
    std::vector<std::vector<V2>> sector_nodes(noisy ? res.half_lines.size() : 0);
    if (noisy) {
        for (const auto& h : res.half_lines) bilinear.push_back(h.h_mm);
        LocalFitWindow win;
        win.radial_half_mm = kLocalFitRadialSteps * std::max(spacing, m.dx_mm);
        win.sector_half_rad = kPi / n;
        win.tangential_min_mm = kLocalFitTangentialBscans * m.dy_mm;
        local_fit_samples(m, res.centre_mm, geo.grid_to_anatomical(), win, res.half_lines,
                          &sector_nodes, params.radius_mm);
        res.noise_adaptive_samples = true;
    }
    // CFT as a model estimate (docs/algorithms/cube.md "CFT"): every interior fitted with its
    // start height free; CFT = the mean of those heights (the shared P0.y of Eq. 7.5); then
    // every half-line fitted with P0 = (0, CFT) as the thesis' model has it.
    res.cft_sample_mm = res.cft_mm;
    std::vector<CubeHalfLine> free_pass;  // each half-line fitted with its own P0.y
    {
        // The CFT pass only feeds P0.y into a mean: a relative energy change of 1e-6 leaves CFT
        // within 0.01 um of the 1e-10 result (12 noisy 193-B-scan phantoms) at ~60 % of the
        // rounds; the final pass, warm-started from this one, keeps SPEC §4.5's 1e-10.
        constexpr double kCftPassTolerance = 1e-6;
        FitSettings free_fs{params.max_rounds, std::max(kCftPassTolerance, params.energy_tolerance),
                            true, params.rim_point, crest_mm};
        free_pass.reserve(res.half_lines.size());
        double sum = 0.0;
        int count = 0;
        // Every half-line's first sample is the centre: under noise the bilinear M there (4
        // nodes, 2-4 um of noise) entered all 24 fits alike, an error no mean removes; the
        // centre's quadratic surface averages the nodes of its window instead (+-0.2 mm at 1
        // axial pixel: ~140 / 350 nodes at 61 / 193 B-scans).
        const double centre_sample = std::isnan(centre_sample_mm) ? res.cft_mm : centre_sample_mm;
        for (const auto& h0 : res.half_lines) {
            CubeHalfLine& h = free_pass.emplace_back(h0);
            fit_half_line(h, centre_sample, params, free_fs);
            if (!h.valid) continue;
            sum += h.interior.control[0].y();
            ++count;
        }
        if (count > 0) res.cft_mm = sum / count;
    }
    // Under noise the final fit uses the sector bins (docs/algorithms/cube.md "Radial samples
    // under noise"), started from the CFT pass's curves.
    if (noisy) sector_bin_samples(sector_nodes, res.half_lines);
    for (std::size_t i = 0; i < res.half_lines.size(); ++i) {
        CubeHalfLine& h = res.half_lines[i];
        h.h_mm[0] = res.cft_mm;
        const BilinearSamples regular{radii, bilinear.empty() ? h.h_mm : bilinear[i]};
        fit_half_line(h, res.cft_mm, params,
                      {params.max_rounds, params.energy_tolerance, false, params.rim_point, crest_mm},
                      &free_pass[i], bilinear.empty() ? nullptr : &regular);
    }

    // ---- parameters (SPEC §4.6) --------------------------------------------------------------
    int valid = 0;
    int missing_pit = 0;
    int flat_count = 0;
    double rim_sum = 0.0;
    double slope_sum = 0.0;
    double flat_sum = 0.0;
    double alpha_sum = 0.0;
    double beta_sum = 0.0;
    double sse = 0.0;
    double count = 0.0;
    double vr = 0.0;
    double vir = 0.0;
    for (const auto& h : res.half_lines) {
        missing_pit += h.num_missing_interior;
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
        const double ns = h.interior.num_samples + h.exterior.num_samples;
        sse += bilinear.empty() ? h.interior.sse_mm2 + h.exterior.sse_mm2
                                : ns * 1e-6 * h.rmse_um * h.rmse_um;
        count += ns;
    }
    if (valid == 0) {
        throw AnalysisError("no half-line could be fitted (" + res.half_lines.front().problem +
                            "): is the fovea inside the scan?");
    }
    const double inv = 1.0 / valid;
    res.rim_height_mm = rim_sum * inv;                  // Eq. 7.15
    res.pit_depth_mm = res.rim_height_mm - res.cft_mm;  // Eq. 7.19
    res.max_pit_slope_deg = slope_sum * inv;            // Eq. 7.21 on atan(s_i)
    res.alpha_mean_mm = alpha_sum * inv;
    res.beta_mean_mm = beta_sum * inv;
    if (flat_count == valid) res.pit_flat_diameter_mm = 2.0 * flat_sum / flat_count;  // Eq. 7.26
    res.rmse_um = 1000.0 * std::sqrt(sse / count);
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
                const V2 q = res.centre_mm + r * h.direction;
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
    } else if (!res.line_scan) {
        res.notes.push_back("disks and volumes need every half-line: omitted");
    }
    if (res.line_scan) {
        res.notes.push_back(
            "line scan: 2-D parameters only (SPEC §4.8); the 3-D parameters "
            "(disks, volumes) are omitted");
    }

    // ---- QC ----------------------------------------------------------------------------------
    if (missing_pit > 0) res.qc_flags.push_back("missing values in the pit");
    if (res.rmse_um > params.rmse_warning_um) res.qc_flags.push_back("fit RMSE high");
    if (!res.line_scan && geo.spacing().positions_known && !geo.spacing().uniform) {
        res.qc_flags.push_back("B-scan spacing not uniform");
    }
    if (!geo.oriented_from_positions()) {
        res.qc_flags.push_back("orientation assumed (B-scan positions unusable)");
    }
    if (scan.meta.laterality == io::Laterality::kUnknown) {
        res.qc_flags.push_back("eye unknown: nasal assumed on SLO +x");
    }
    return res;
}

}  // namespace octshape::retina
