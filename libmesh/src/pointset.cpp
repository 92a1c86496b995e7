#include "octshape/mesh/pointset.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <functional>
#include <limits>
#include <numeric>
#include <queue>
#include <stdexcept>
#include <string>
#include <tuple>
#include <utility>

#include <Eigen/Eigenvalues>

#include "parallel.h"

#include "octshape/error.h"

namespace octshape::mesh {
namespace {

constexpr int kLeafSize = 8;
// Neighbours averaged for the point spacing: the 1-ring of a regular triangulation.
constexpr int kSpacingNeighbours = 6;
// shifted_normals: a candidate plane must pass within this many σ̂ of the point (2.5σ keeps
// 99 % of Gaussian offsets).
constexpr double kCandidateSigmas = 2.5;

double box_distance2(const Eigen::Vector3d& p, const Eigen::Vector3d& lo,
                     const Eigen::Vector3d& hi) {
    double d2 = 0.0;
    for (int k = 0; k < 3; ++k) {
        const double d = std::max({lo(k) - p(k), 0.0, p(k) - hi(k)});
        d2 += d * d;
    }
    return d2;
}

using Seconds = std::chrono::duration<double>;

double seconds_since(std::chrono::steady_clock::time_point t0) {
    return Seconds(std::chrono::steady_clock::now() - t0).count();
}

// Eigen-decomposition of a symmetric 3×3 matrix, eigenvalues in DEcreasing order
// (the thesis' λ1 ≥ λ2 ≥ λ3; Eigen returns them increasing).
struct Eigen3 {
    Eigen::Vector3d values;   // λ1 ≥ λ2 ≥ λ3
    Eigen::Matrix3d vectors;  // column k belongs to values(k)
};

// The iterative (QL) solver: used once per point for the PCA normals, where the smallest
// eigenvector of a nearly flat covariance must be exact to machine precision.
Eigen3 eigen_decreasing(const Eigen::Matrix3d& M) {
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(M);
    Eigen3 out;
    for (int k = 0; k < 3; ++k) {
        out.values(k) = solver.eigenvalues()(2 - k);
        out.vectors.col(k) = solver.eigenvectors().col(2 - k);
    }
    return out;
}

// The closed-form solver (SelfAdjointEigenSolver::computeDirect, Smith's trigonometric roots
// plus cross-product eigenvectors), ~5× faster, used in the iterations (whose thresholds are
// counted by eigenvalues_at_least below). Its eigenvectors of a (nearly) repeated eigenvalue
// are arbitrary within their eigenspace, as are the QL solver's; the iterations use e1 where
// λ2 < τ (Eq. 4.6 with λ̃ = (1,0,0)), e3 where λ3 < τ ≤ λ2 (λ̃ = (1,1,0): C̃ = I − e3e3ᵀ) and
// x1 of an edge point (a1 ≥ τ > a2, Eq. 4.10/4.14): each is set apart from the others by the
// threshold (for e1 when τ ≤ 1/3, since trace C = 1 gives λ1 ≥ 1/3). Positions on a 50k-point cube differ from
// the QL solver's by ≤ 1.7e-11 after 30 iterations (docs/algorithms/pointset.md).
Eigen3 eigen_decreasing_direct(const Eigen::Matrix3d& M) {
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver;
    solver.computeDirect(M);
    Eigen3 out;
    for (int k = 0; k < 3; ++k) {
        out.values(k) = solver.eigenvalues()(2 - k);
        out.vectors.col(k) = solver.eigenvectors().col(2 - k);
    }
    return out;
}

// The number of eigenvalues of the symmetric M that are ≥ t, without solving for them:
// by Sylvester's law of inertia the negative eigenvalues of B = M − tI are as many as the sign
// changes in the sequence of its leading principal minors (1, D1, D2, D3) when none is zero;
// the rare exact zero falls back to the eigenvalues. Used for the thresholds of the binary
// optimisation (§4.1.1) and of Eq. 4.10, which only ask how many eigenvalues reach τ.
int eigenvalues_at_least(const Eigen::Matrix3d& M, double t) {
    const double b00 = M(0, 0) - t;
    const double b11 = M(1, 1) - t;
    const double b22 = M(2, 2) - t;
    const double d1 = b00;
    const double d2 = b00 * b11 - M(0, 1) * M(0, 1);
    const double d3 = b00 * (b11 * b22 - M(1, 2) * M(1, 2)) -
                      M(0, 1) * (M(0, 1) * b22 - M(1, 2) * M(0, 2)) +
                      M(0, 2) * (M(0, 1) * M(1, 2) - b11 * M(0, 2));
    if (d1 == 0.0 || d2 == 0.0 || d3 == 0.0) {
        Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver;
        solver.computeDirect(M, Eigen::EigenvaluesOnly);
        return static_cast<int>((solver.eigenvalues().array() >= t).count());
    }
    const int negative = (d1 < 0.0 ? 1 : 0) + ((d1 < 0.0) != (d2 < 0.0) ? 1 : 0) +
                         ((d2 < 0.0) != (d3 < 0.0) ? 1 : 0);
    return 3 - negative;
}

// Σ x xᵀ accumulated in its 6 distinct entries (Eigen's rankUpdate is an out-of-line call
// per 3-vector, the dominant cost of the inner loops before).
struct Sym3 {
    double xx = 0, xy = 0, xz = 0, yy = 0, yz = 0, zz = 0;
    template <class V>
    void add(const V& x) {
        xx += x(0) * x(0);
        xy += x(0) * x(1);
        xz += x(0) * x(2);
        yy += x(1) * x(1);
        yz += x(1) * x(2);
        zz += x(2) * x(2);
    }
    [[nodiscard]] Eigen::Matrix3d matrix() const {
        Eigen::Matrix3d M;
        M << xx, xy, xz, xy, yy, yz, xz, yz, zz;
        return M;
    }
};

}  // namespace

// ---------------------------------------------------------------- k-d tree

KdTree::KdTree(const Vertices& points) : P_(points) {
    if (!P_.allFinite()) throw DataError("points: a coordinate is not finite");
    const int n = static_cast<int>(P_.rows());
    order_.resize(static_cast<std::size_t>(n));
    std::iota(order_.begin(), order_.end(), 0);
    if (n == 0) return;
    nodes_.reserve(static_cast<std::size_t>(2 * (n / kLeafSize + 1)) + 1);
    nodes_.emplace_back();
    build(0, 0, n);
}

void KdTree::build(int node, int first, int count) {
    Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
    Eigen::Vector3d hi = -lo;
    for (int k = first; k < first + count; ++k) {
        const Eigen::Vector3d p = P_.row(order_[static_cast<std::size_t>(k)]).transpose();
        lo = lo.cwiseMin(p);
        hi = hi.cwiseMax(p);
    }
    nodes_[static_cast<std::size_t>(node)].lo = lo;
    nodes_[static_cast<std::size_t>(node)].hi = hi;
    if (count <= kLeafSize) {
        nodes_[static_cast<std::size_t>(node)].first = first;
        nodes_[static_cast<std::size_t>(node)].count = count;
        return;
    }
    int axis = 0;
    (hi - lo).maxCoeff(&axis);
    const int half = count / 2;
    const auto begin = order_.begin() + first;
    std::nth_element(begin, begin + half, begin + count, [&](int a, int b) {
        const double pa = P_(a, axis);
        const double pb = P_(b, axis);
        return pa < pb || (pa == pb && a < b);
    });
    const int left = static_cast<int>(nodes_.size());
    nodes_[static_cast<std::size_t>(node)].first = left;
    nodes_[static_cast<std::size_t>(node)].count = 0;
    nodes_.emplace_back();
    nodes_.emplace_back();
    build(left, first, half);
    build(left + 1, first + half, count - half);
}

std::vector<int> KdTree::nearest(const Eigen::Vector3d& p, int k) const {
    std::vector<int> out;
    if (k <= 0 || nodes_.empty()) return out;
    // Max-heap of the best k so far, ordered by (distance², index).
    using Entry = std::pair<double, int>;
    std::priority_queue<Entry> best;
    const auto worst = [&] {
        return static_cast<int>(best.size()) < k ? std::numeric_limits<double>::infinity()
                                                   : best.top().first;
    };
    std::vector<int> stack{0};
    while (!stack.empty()) {
        const Node& node = nodes_[static_cast<std::size_t>(stack.back())];
        stack.pop_back();
        if (box_distance2(p, node.lo, node.hi) > worst()) continue;
        if (node.count > 0) {
            for (int m = node.first; m < node.first + node.count; ++m) {
                const int j = order_[static_cast<std::size_t>(m)];
                const double d2 = (P_.row(j).transpose() - p).squaredNorm();
                if (static_cast<int>(best.size()) < k) {
                    best.emplace(d2, j);
                } else if (Entry(d2, j) < best.top()) {
                    best.pop();
                    best.emplace(d2, j);
                }
            }
            continue;
        }
        // Visit the nearer child first (pushed last).
        const Node& a = nodes_[static_cast<std::size_t>(node.first)];
        const Node& b = nodes_[static_cast<std::size_t>(node.first) + 1];
        const bool a_first = box_distance2(p, a.lo, a.hi) <= box_distance2(p, b.lo, b.hi);
        stack.push_back(a_first ? node.first + 1 : node.first);
        stack.push_back(a_first ? node.first : node.first + 1);
    }
    out.resize(best.size());
    for (auto it = out.rbegin(); it != out.rend(); ++it) {
        *it = best.top().second;
        best.pop();
    }
    return out;
}

std::vector<int> KdTree::within(const Eigen::Vector3d& p, double radius) const {
    std::vector<int> out;
    within(p, radius, out);
    std::sort(out.begin(), out.end());
    return out;
}

void KdTree::within(const Eigen::Vector3d& p, double radius, std::vector<int>& out) const {
    out.clear();
    if (nodes_.empty() || !(radius >= 0.0)) return;
    const double r2 = radius * radius;
    std::vector<int> stack{0};
    while (!stack.empty()) {
        const Node& node = nodes_[static_cast<std::size_t>(stack.back())];
        stack.pop_back();
        if (box_distance2(p, node.lo, node.hi) > r2) continue;
        if (node.count > 0) {
            for (int m = node.first; m < node.first + node.count; ++m) {
                const int j = order_[static_cast<std::size_t>(m)];
                if ((P_.row(j).transpose() - p).squaredNorm() <= r2) out.push_back(j);
            }
        } else {
            stack.push_back(node.first);
            stack.push_back(node.first + 1);
        }
    }
}

// ---------------------------------------------------------------- neighbourhoods, normals

double mean_point_spacing(const Vertices& points, const KdTree& tree, int threads) {
    const int n = static_cast<int>(points.rows());
    if (n < kSpacingNeighbours + 1) return 0.0;
    std::vector<double> per_point(static_cast<std::size_t>(n));
    detail::parallel_for(n, threads, [&](int begin, int end) {
        for (int i = begin; i < end; ++i) {
            const Eigen::Vector3d p = points.row(i).transpose();
            // The nearest k + 1 include i itself (distance 0) unless duplicates exist.
            const std::vector<int> near = tree.nearest(p, kSpacingNeighbours + 1);
            double s = 0.0;
            for (const int j : near) s += (points.row(j).transpose() - p).norm();
            per_point[static_cast<std::size_t>(i)] = s / static_cast<double>(near.size() - 1);
        }
    });
    // Summed in index order by one thread: the same result for any thread count.
    double sum = 0.0;
    for (const double s : per_point) sum += s;
    return sum / n;
}

Csr point_neighbourhoods(const Vertices& points,
                         const KdTree& tree,
                         double radius,
                         int min_count,
                         int threads) {
    const int n = static_cast<int>(points.rows());
    std::vector<std::vector<int>> rows(static_cast<std::size_t>(n));
    detail::parallel_for(n, threads, [&](int begin, int end) {
        for (int i = begin; i < end; ++i) {
            const Eigen::Vector3d p = points.row(i).transpose();
            std::vector<int> row = tree.within(p, radius);
            if (static_cast<int>(row.size()) < min_count) {
                row = tree.nearest(p, min_count);
                std::sort(row.begin(), row.end());
            }
            // i first, then the rest ascending.
            std::vector<int>& dst = rows[static_cast<std::size_t>(i)];
            dst.reserve(row.size() + 1);
            dst.push_back(i);
            for (const int j : row) {
                if (j != i) dst.push_back(j);
            }
        }
    });
    return Csr::from_rows(rows);
}

namespace {

// Least-squares planes of the neighbourhoods: centroid, unit normal (smallest eigenvector of
// the covariance, unoriented) and the smallest eigenvalue (mean squared distance to the plane).
struct PlaneFits {
    Vertices centroid;             // #P×3
    Vertices normal;               // #P×3
    std::vector<double> residual2; // #P, length²
    std::vector<double> flatness;  // #P, λ3 / (λ1 + λ2 + λ3): 0 for points on a plane
};

PlaneFits fit_planes(const Vertices& points, const Csr& nb, int threads) {
    const int n = static_cast<int>(points.rows());
    PlaneFits f{Vertices(n, 3), Vertices(n, 3), std::vector<double>(static_cast<std::size_t>(n)),
                std::vector<double>(static_cast<std::size_t>(n))};
    detail::parallel_for(n, threads, [&](int begin, int end) {
        for (int i = begin; i < end; ++i) {
            Eigen::Vector3d mean = Eigen::Vector3d::Zero();
            for (int k = nb.begin(i); k < nb.end(i); ++k) {
                mean += points.row(nb.item(k)).transpose();
            }
            mean /= nb.size(i);
            Sym3 C;
            for (int k = nb.begin(i); k < nb.end(i); ++k) {
                C.add(Eigen::Vector3d(points.row(nb.item(k)).transpose() - mean));
            }
            const Eigen3 e = eigen_decreasing(C.matrix());
            f.centroid.row(i) = mean.transpose();
            f.normal.row(i) = e.vectors.col(2).transpose();
            f.residual2[static_cast<std::size_t>(i)] = std::max(0.0, e.values(2)) / nb.size(i);
            const double trace = e.values.sum();
            f.flatness[static_cast<std::size_t>(i)] =
                trace > 0.0 ? std::max(0.0, e.values(2)) / trace : 0.0;
        }
    });
    return f;
}

// Consistent orientation of N in place: Prim's minimum spanning tree (pca_normals).
void orient_normals(const Vertices& points, const Csr& nb, Vertices& N) {
    const int n = static_cast<int>(points.rows());
    // Symmetric neighbour graph (Ω_i may be asymmetric where min_count added points).
    std::vector<int> degree(static_cast<std::size_t>(n), 0);
    for (int i = 0; i < n; ++i) {
        for (int k = nb.begin(i) + 1; k < nb.end(i); ++k) {
            ++degree[static_cast<std::size_t>(i)];
            ++degree[static_cast<std::size_t>(nb.item(k))];
        }
    }
    Csr graph;
    graph.offsets.assign(static_cast<std::size_t>(n) + 1, 0);
    for (int i = 0; i < n; ++i) {
        graph.offsets[static_cast<std::size_t>(i) + 1] =
            graph.offsets[static_cast<std::size_t>(i)] + degree[static_cast<std::size_t>(i)];
    }
    graph.items.resize(static_cast<std::size_t>(graph.offsets.back()));
    std::vector<int> fill(graph.offsets.begin(), graph.offsets.end() - 1);
    for (int i = 0; i < n; ++i) {
        for (int k = nb.begin(i) + 1; k < nb.end(i); ++k) {
            const int j = nb.item(k);
            graph.items[static_cast<std::size_t>(fill[static_cast<std::size_t>(i)]++)] = j;
            graph.items[static_cast<std::size_t>(fill[static_cast<std::size_t>(j)]++)] = i;
        }
    }
    // Seeds: the highest point of each component, visited in order of decreasing z.
    std::vector<int> by_height(static_cast<std::size_t>(n));
    std::iota(by_height.begin(), by_height.end(), 0);
    std::stable_sort(by_height.begin(), by_height.end(),
                     [&](int a, int b) { return points(a, 2) > points(b, 2); });
    std::vector<std::uint8_t> done(static_cast<std::size_t>(n), 0);
    // Prim's algorithm: (cost, point, parent), smallest cost first; ties by point index.
    // An entry is queued only if it beats the best (cost, parent) queued for that point so far:
    // the dominated ones would be popped after it and skipped, so the tree is the same with
    // far fewer heap operations.
    using Item = std::tuple<double, int, int>;
    std::priority_queue<Item, std::vector<Item>, std::greater<>> queue;
    std::vector<std::pair<double, int>> best(static_cast<std::size_t>(n),
                                             {std::numeric_limits<double>::infinity(), n});
    for (const int seed : by_height) {
        if (done[static_cast<std::size_t>(seed)] != 0) continue;
        if (N(seed, 2) < 0.0) N.row(seed) *= -1.0;
        queue.emplace(0.0, seed, seed);
        while (!queue.empty()) {
            const auto [cost, i, parent] = queue.top();
            queue.pop();
            if (done[static_cast<std::size_t>(i)] != 0) continue;
            done[static_cast<std::size_t>(i)] = 1;
            if (N.row(i).dot(N.row(parent)) < 0.0) N.row(i) *= -1.0;
            for (int k = graph.begin(i); k < graph.end(i); ++k) {
                const int j = graph.item(k);
                if (done[static_cast<std::size_t>(j)] != 0) continue;
                const std::pair<double, int> entry(1.0 - std::abs(N.row(i).dot(N.row(j))), i);
                if (!(entry < best[static_cast<std::size_t>(j)])) continue;
                best[static_cast<std::size_t>(j)] = entry;
                queue.emplace(entry.first, j, i);
            }
        }
    }
}

}  // namespace

Vertices pca_normals(const Vertices& points, const Csr& nb, int threads) {
    PlaneFits f = fit_planes(points, nb, threads);
    orient_normals(points, nb, f.normal);
    return f.normal;
}

Vertices shifted_normals(const Vertices& points,
                           const Csr& nb,
                           const Csr& support,
                           double inlier_sigmas,
                           int threads) {
    if (!(inlier_sigmas > 0.0 && std::isfinite(inlier_sigmas))) {
        throw UsageError("inlier_sigmas must be finite and > 0");
    }
    const int n = static_cast<int>(points.rows());
    Vertices N(n, 3);
    if (n == 0) return N;
    const PlaneFits f = fit_planes(points, nb, threads);
    Vertices pca = f.normal;
    orient_normals(points, nb, pca);
    // σ̂: the median RMS distance of a neighbourhood to its plane. Most neighbourhoods of a
    // surface with sharp features are flat, so this is the noise along the normal (plus the
    // curvature's sagitta on a curved surface). The small floor keeps noise-free input working.
    std::vector<double> rms(static_cast<std::size_t>(n));
    for (int i = 0; i < n; ++i) {
        rms[static_cast<std::size_t>(i)] = std::sqrt(f.residual2[static_cast<std::size_t>(i)]);
    }
    const auto mid = rms.begin() + n / 2;
    std::nth_element(rms.begin(), mid, rms.end());
    const double extent = (points.colwise().maxCoeff() - points.colwise().minCoeff()).norm();
    const double t = kCandidateSigmas * *mid + 1e-9 * extent;
    const double t_fit = inlier_sigmas * *mid + 1e-9 * extent;

    using Vec3 = Eigen::Vector3d;
    using CMap = Eigen::Map<const Vec3>;
    const double* const v = points.data();
    const double* const cn = f.normal.data();
    const double* const cc = f.centroid.data();
    const int* const items = nb.items.data();
    const int* const offsets = nb.offsets.data();
    const int* const sitems = support.items.data();
    const int* const soffsets = support.offsets.data();
    detail::parallel_for(n, threads, [&](int begin, int end) {
        for (int i = begin; i < end; ++i) {
            const CMap vi(v + 3 * i);
            // Candidates: the planes of the neighbourhoods Ω_j, j ∈ Ω_i, that pass within t of
            // v_i; the flattest wins (ties: the first in Ω_i's order).
            int best = -1;
            double best_flatness = std::numeric_limits<double>::infinity();
            for (int k = offsets[i]; k < offsets[i + 1]; ++k) {
                const int j = items[k];
                if (std::abs(CMap(cn + 3 * j).dot(vi - CMap(cc + 3 * j))) > t) continue;
                if (f.flatness[static_cast<std::size_t>(j)] < best_flatness) {
                    best = j;
                    best_flatness = f.flatness[static_cast<std::size_t>(j)];
                }
            }
            const int from = best < 0 ? i : best;
            Vec3 normal = CMap(cn + 3 * from);
            Vec3 centre = CMap(cc + 3 * from);
            // Refit twice: the plane of the inliers of Ω_i only (the points of v_i's own face
            // near an edge), so the normal no longer blends in the other face.
            for (int round = 0; round < 2; ++round) {
                Vec3 sum = Vec3::Zero();
                Sym3 S;
                int m = 0;
                for (int q = soffsets[i]; q < soffsets[i + 1]; ++q) {
                    const Vec3 d = CMap(v + 3 * sitems[q]) - vi;
                    if (std::abs(normal.dot(CMap(v + 3 * sitems[q]) - centre)) > t_fit) continue;
                    sum += d;
                    S.add(d);
                    ++m;
                }
                if (m < 3) break;
                const Vec3 mean = sum / m;
                const Eigen::Matrix3d C = S.matrix() / m - mean * mean.transpose();
                normal = eigen_decreasing(C).vectors.col(2);
                centre = vi + mean;
            }
            // Orientation: that of the (consistently oriented) PCA normal of the same point,
            // which blends the faces near an edge and so lies within 90° of each of them.
            if (normal.dot(pca.row(i).transpose()) < 0.0) normal = -normal;
            N.row(i) = normal.transpose();
        }
    });
    return N;
}


// ---------------------------------------------------------------- edge snapping

namespace {

// One face plane near a feature: n·x = offset, with the centroid of the points it was fitted to.
struct FacePlane {
    Eigen::Vector3d normal;
    double offset = 0;
    Eigen::Vector3d centroid;
};

// The point of the piecewise-planar surface bounded by up to 3 face planes that v snaps to: for
// every non-empty subset S of the planes, the nearest point of their intersection (a plane, a
// line, a corner), kept if it lies on the same side of every other plane as the faces of S do
// (their centroids). Among the kept ones, the intersection of the most planes that v lies
// within `within` of wins (ties: the nearest); if v is within noise of no plane, the nearest.
// Why the intersection: a point within noise of both faces of an edge cannot be told to belong
// to either, and sending it to the nearer plane is biased — noise outwards of face A (past
// plane A) projects back onto A, noise inwards may be nearer to B and stays inside A's plane,
// which rounds the edge (measured: +2.3° mean over 60 edges, docs/algorithms/pointset.md); on
// the intersection it lies on both planes and biases neither. False if none is kept. `on_one`
// receives the plane index when the winner lies on one plane only, else −1.
bool nearest_on_faces(const Eigen::Vector3d& v, const std::vector<FacePlane>& planes,
                      double within, Eigen::Vector3d* best, int* on_one) {
    const int np = static_cast<int>(planes.size());
    double best_d2 = std::numeric_limits<double>::infinity();
    int best_k = 0;
    int near_mask = 0;
    for (int p = 0; p < np; ++p) {
        const FacePlane& f = planes[static_cast<std::size_t>(p)];
        if (std::abs(f.normal.dot(v) - f.offset) <= within) near_mask |= 1 << p;
    }
    for (int mask = 1; mask < (1 << np); ++mask) {
        int k = 0;
        Eigen::Matrix3d A = Eigen::Matrix3d::Zero();
        Eigen::Vector3d b = Eigen::Vector3d::Zero();
        Eigen::Vector3d centre = Eigen::Vector3d::Zero();
        int single = -1;
        for (int p = 0; p < np; ++p) {
            if ((mask & (1 << p)) == 0) continue;
            A.row(k) = planes[static_cast<std::size_t>(p)].normal.transpose();
            b(k) = planes[static_cast<std::size_t>(p)].offset;
            centre += planes[static_cast<std::size_t>(p)].centroid;
            single = p;
            ++k;
        }
        centre /= k;
        // x = v − Aᵀ (A Aᵀ)⁻¹ (A v − b): the nearest point of {A x = b} (A's rows unit normals
        // ≥ 45° apart, so A Aᵀ is well conditioned unless three normals are nearly coplanar).
        using Rows = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor, 3, 3>;
        using Gram = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, 3, 3>;
        using Vec = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, 3, 1>;
        const Rows As = A.topRows(k);
        const Gram G = As * As.transpose();
        if (G.determinant() < 1e-3) continue;
        const Vec residual = As * v - b.head(k);
        const Eigen::Vector3d x = v - As.transpose() * G.ldlt().solve(residual);
        bool valid = true;
        for (int p = 0; p < np && valid; ++p) {
            if ((mask & (1 << p)) != 0) continue;
            const FacePlane& f = planes[static_cast<std::size_t>(p)];
            const double side = f.normal.dot(centre) - f.offset;
            valid = (f.normal.dot(x) - f.offset) * side >= 0.0;
        }
        const double d2 = (x - v).squaredNorm();
        // Within noise of several planes: their intersection (the most planes) wins.
        const int rank = (mask & ~near_mask) == 0 ? k : 0;
        if (valid && (rank > best_k || (rank == best_k && d2 < best_d2))) {
            best_k = rank;
            best_d2 = d2;
            *best = x;
            *on_one = k == 1 ? single : -1;
        }
    }
    return best_d2 < std::numeric_limits<double>::infinity();
}

}  // namespace

// ---------------------------------------------------------------- denoiser

void PointSetParams::validate() const {
    const auto bad = [](const std::string& what) { throw UsageError(what); };
    if (!(tau > 0.0 && tau < 1.0)) bad("tau must be in (0, 1)");
    if (!(rho > 0.0 && rho <= M_PI)) bad("rho must be in (0, pi] radians");
    if (iterations < 0) bad("iterations must be >= 0");
    if (!(damping >= 0.0) || !std::isfinite(damping)) bad("damping must be finite and >= 0");
    if (!(lambda > 0.0 && lambda <= 1.0)) bad("lambda must be in (0, 1]");
    if (radius && !(*radius > 0.0 && std::isfinite(*radius))) bad("radius must be > 0");
    if (epsilon && !(*epsilon >= 0.0 && std::isfinite(*epsilon))) bad("epsilon must be >= 0");
    if (min_neighbours < 4) bad("min_neighbours must be >= 4");
    if (threads < 1) bad("threads must be >= 1");
    if (normals != NormalEstimator::kPca && normals != NormalEstimator::kShifted) {
        bad("normals must be kPca or kShifted");
    }
    if (!(inlier_sigmas > 0.0 && std::isfinite(inlier_sigmas))) {
        bad("inlier_sigmas must be finite and > 0");
    }
    if (!(support >= 1.0 && std::isfinite(support))) bad("support must be finite and >= 1");
    if (!(snap_group_deg > 0.0 && snap_group_deg < 90.0)) bad("snap_group_deg must be in (0, 90)");
    if (!(snap_support >= 1.0 && std::isfinite(snap_support))) {
        bad("snap_support must be finite and >= 1");
    }
    if (!(snap_sigmas >= 0.0 && std::isfinite(snap_sigmas))) {
        bad("snap_sigmas must be finite and >= 0");
    }
}

// ---------------------------------------------------------------- the denoiser's stages
//
// pointset_denoise runs, in this order (docs/algorithms/pointset.md):
//   setup            k-d tree, mean spacing, r and ε, Ω_i, the initial normals (PCA or shifted)
//   per iteration:   filter_normals   (Eq. 4.1-4.6, binary optimisation §4.1.1)
//                    classify_points  (Eq. 4.7-4.10: flat, edge with its direction, corner)
//                    update_vertices  (Eq. 4.11-4.17, bounded by ε)
//   snap_edges       onto the refitted face planes near features (beyond §4.1)
// Each parallel pass reads the previous pass' arrays and writes only row i of its own, so the
// results are bit-identical for any thread count (parallel.h).

namespace {

using Vec3 = Eigen::Vector3d;
using CMap = Eigen::Map<const Vec3>;

struct Setup {
    KdTree tree;
    Csr nb;      // Ω_i: i first, then ascending
    Vertices N;  // consistently oriented initial normals
};

Setup setup(const Vertices& points, const PointSetParams& params, PointSetResult& out) {
    const int n = static_cast<int>(points.rows());
    Setup st{KdTree(points), {}, {}};
    out.mean_spacing = mean_point_spacing(points, st.tree, params.threads);
    out.radius = params.radius ? *params.radius : 2.0 * out.mean_spacing;  // §4.2.1
    if (!(out.radius > 0.0)) throw AnalysisError("points: all points coincide");
    out.epsilon = params.epsilon ? *params.epsilon : out.radius;
    st.nb = point_neighbourhoods(points, st.tree, out.radius, params.min_neighbours,
                                 params.threads);
    out.mean_neighbourhood = static_cast<double>(st.nb.items.size()) / n;
    if (params.normals == NormalEstimator::kShifted) {
        const Csr support = point_neighbourhoods(points, st.tree, params.support * out.radius,
                                                 params.min_neighbours, params.threads);
        st.N = shifted_normals(points, st.nb, support, params.inlier_sigmas, params.threads);
    } else {
        st.N = pca_normals(points, st.nb, params.threads);
    }
    return st;
}

// Constants of the iterations, from the parameters and r.
struct IterationConstants {
    double cos_rho = 0;     // Eq. 4.2 / 4.8 angle threshold
    double r2 = 0;          // r²
    double c2 = 0;          // (2 sin(ρ/2))²: the width of the normal term of Eq. 4.17
    double flat_trace = 0;  // trace of A_i for a flat disc of radius r (r²/2)
};

// (1) Normal filtering, Eq. 4.1–4.6: Nf from N.
void filter_normals(const Csr& nb, const Vertices& N, const PointSetParams& params,
                    const IterationConstants& ic, Vertices& Nf) {
    const int n = static_cast<int>(N.rows());
    const int* const items = nb.items.data();
    const int* const offsets = nb.offsets.data();
    const double cos_rho = ic.cos_rho;
    const double* const nrm = N.data();
    double* const nf = Nf.data();
    detail::parallel_for(n, params.threads, [&](int begin, int end) {
        for (int i = begin; i < end; ++i) {
            const CMap ni(nrm + 3 * i);
            Sym3 C;
            int count = 0;
            for (int k = offsets[i]; k < offsets[i + 1]; ++k) {
                const CMap nj(nrm + 3 * items[k]);
                if (ni.dot(nj) < cos_rho) continue;  // Eq. 4.2: w_ij = 0
                C.add(nj);
                ++count;
            }
            // count ≥ 1: n_i itself
            const Eigen::Matrix3d Cm = C.matrix() / count;
            // Binary optimisation (§4.1.1): λ̃ = (1,1,1) if λ3 ≥ τ, (1,1,0) if λ2 ≥ τ,
            // else (1,0,0); C̃ n_i (Eq. 4.5) is then n_i, (I − e3e3ᵀ) n_i or e1e1ᵀ n_i, so
            // only kept = 1, 2 need an eigenvector (e1 resp. e3).
            const int kept = std::max(1, eigenvalues_at_least(Cm, params.tau));
            Vec3 filtered = (params.damping + 1.0) * ni;  // Eq. 4.6, kept = 3
            if (kept < 3) {
                const Eigen3 e = eigen_decreasing_direct(Cm);
                if (kept == 2) {
                    filtered -= e.vectors.col(2).dot(ni) * e.vectors.col(2);
                } else {
                    filtered = params.damping * ni + e.vectors.col(0).dot(ni) * e.vectors.col(0);
                }
            }
            const double len = filtered.norm();
            Eigen::Map<Vec3>(nf + 3 * i) = len > 0.0 ? Vec3(filtered / len) : Vec3(ni);
        }
    });
}

// (2) Classification, Eq. 4.7–4.10, of the positions V with the filtered normals N: classes,
// and x1 of A_i (the edge direction) at edge points in edge_dir (zero elsewhere).
void classify_points(const Csr& nb, const Vertices& V, const Vertices& N,
                     const PointSetParams& params, const IterationConstants& ic,
                     std::vector<PointClass>& classes, Vertices& edge_dir) {
    const int n = static_cast<int>(V.rows());
    const int* const items = nb.items.data();
    const int* const offsets = nb.offsets.data();
    const double cos_rho = ic.cos_rho;
    const double flat_trace = ic.flat_trace;
    const double* const v = V.data();
    const double* const fn = N.data();
    double* const xd = edge_dir.data();
    detail::parallel_for(n, params.threads, [&](int begin, int end) {
        for (int i = begin; i < end; ++i) {
            const CMap ni(fn + 3 * i);
            const CMap vi(v + 3 * i);
            // One pass: moments of d_j = v_j − v_i (lengths ~ r, no cancellation), then
            // A = Σ d dᵀ / m − d̄ d̄ᵀ, the covariance about v_c (Eq. 4.7–4.8).
            Vec3 sum = Vec3::Zero();
            Sym3 S;
            int count = 0;
            for (int k = offsets[i]; k < offsets[i + 1]; ++k) {
                const int j = items[k];
                if (ni.dot(CMap(fn + 3 * j)) < cos_rho) continue;  // Eq. 4.8
                const Vec3 d = CMap(v + 3 * j) - vi;
                sum += d;
                S.add(d);
                ++count;
            }
            const Vec3 mean = sum / count;  // v_c − v_i
            const Eigen::Matrix3d A = S.matrix() / count - mean * mean.transpose();  // Eq. 4.7
            // Eq. 4.10 on a_k / (r²/2): two eigenvalues ≥ τ flat, one edge, none or three
            // corner; only an edge point needs its eigenvector x1 (Eq. 4.14).
            const int above = eigenvalues_at_least(A, params.tau * flat_trace);
            const PointClass cls = above == 2   ? PointClass::kFlat
                                   : above == 1 ? PointClass::kEdge
                                                : PointClass::kCorner;
            classes[static_cast<std::size_t>(i)] = cls;
            Eigen::Map<Vec3>(xd + 3 * i) = cls == PointClass::kEdge
                                               ? Vec3(eigen_decreasing_direct(A).vectors.col(0))
                                               : Vec3::Zero();
        }
    });
}

// (3) Vertex update, Eq. 4.11–4.17: Vn from V; a candidate farther than ε from the input
// point (or not finite) is refused, the point kept and counted in `held`.
void update_vertices(const Vertices& points, const Csr& nb, const Vertices& V, const Vertices& N,
                     const std::vector<PointClass>& classes, const Vertices& edge_dir,
                     const PointSetParams& params, const IterationConstants& ic, double epsilon,
                     Vertices& Vn, std::vector<int>& held) {
    const int n = static_cast<int>(V.rows());
    const int* const items = nb.items.data();
    const int* const offsets = nb.offsets.data();
    const double c2 = ic.c2;
    const double r2 = ic.r2;
    const double* const v = V.data();
    const double* const fn = N.data();
    const double* const xd = edge_dir.data();
    double* const vn = Vn.data();
    const double* const v0 = points.data();
    detail::parallel_for(n, params.threads, [&](int begin, int end) {
        for (int i = begin; i < end; ++i) {
            const CMap ni(fn + 3 * i);
            const CMap vi(v + 3 * i);
            const PointClass cls = classes[static_cast<std::size_t>(i)];
            // A small Tikhonov term μ|v − v_i|² keeps the position unchanged along
            // directions the quadric does not constrain (a rank-deficient Σ N_j).
            const double mu = 1e-3 * (offsets[i + 1] - offsets[i]);
            Vec3 candidate = vi;
            if (cls == PointClass::kCorner) {  // Eq. 4.13, solved for v − v_i
                Sym3 M;
                Vec3 b = Vec3::Zero();
                for (int k = offsets[i]; k < offsets[i + 1]; ++k) {
                    const int j = items[k];
                    const CMap nj(fn + 3 * j);
                    M.add(nj);
                    b += nj.dot(CMap(v + 3 * j) - vi) * nj;
                }
                const Eigen::Matrix3d Mm = M.matrix() + mu * Eigen::Matrix3d::Identity();
                candidate = vi + Mm.ldlt().solve(b);
            } else if (cls == PointClass::kEdge) {  // Eq. 4.14–4.15, solved for v − v_i
                const CMap x1(xd + 3 * i);
                Sym3 M;
                M.add(x1);
                Vec3 b = Vec3::Zero();  // the x1 x1ᵀ v_i term vanishes relative to v_i
                for (int k = offsets[i]; k < offsets[i + 1]; ++k) {
                    const int j = items[k];
                    const Vec3 dj = CMap(v + 3 * j) - vi;
                    const CMap nj(fn + 3 * j);
                    const Vec3 dp = dj - dj.dot(x1) * x1;  // v_j^p − v_i
                    const Vec3 np = nj - nj.dot(x1) * x1;  // ñ_j^p
                    M.add(np);
                    b += np.dot(dp) * np;
                }
                const Eigen::Matrix3d Mm = M.matrix() + mu * Eigen::Matrix3d::Identity();
                candidate = vi + Mm.ldlt().solve(b);
            } else {  // Eq. 4.16–4.17
                double wsum = 0.0;
                double step = 0.0;
                for (int k = offsets[i]; k < offsets[i + 1]; ++k) {
                    const int j = items[k];
                    const Vec3 dj = CMap(v + 3 * j) - vi;
                    const CMap nj(fn + 3 * j);
                    // Eq. 4.17. The thesis divides |ñ_i − ñ_j|² by r², a length²; on unit
                    // normals the width must be dimensionless: we use the chord of the
                    // angle threshold, c = 2 sin(ρ/2) (docs/algorithms/pointset.md). One
                    // exp of the summed exponents.
                    const double w = std::exp(-16.0 * (ni - nj).squaredNorm() / c2 -
                                              4.0 * dj.squaredNorm() / r2);
                    wsum += w;
                    step += w * nj.dot(dj);
                }
                candidate = vi + params.lambda * step / wsum * ni;
            }
            // Eq. 4.11: the bound on the deviation from the input.
            if ((candidate - CMap(v0 + 3 * i)).norm() > epsilon ||
                !candidate.allFinite()) {
                candidate = vi;
                ++held[static_cast<std::size_t>(i)];
            }
            Eigen::Map<Vec3>(vn + 3 * i) = candidate;
        }
    });
}

// The normal groups of a snapping neighbourhood: each member's filtered normal joins the group
// whose mean normal is nearest if within snap_group_deg, else starts a new group; groups whose
// means are within that angle are merged; groups below max(6, 10 % of the members) are
// dropped and at most the 3 largest kept (count 0 = dropped).
struct NormalGroups {
    std::vector<Vec3> sums;   // group normal sums
    std::vector<Vec3> units;  // their directions
    std::vector<int> counts;

    // The surviving group whose mean normal is nearest to nj within the angle, or −1.
    [[nodiscard]] int nearest(const Vec3& nj, double cos_group) const {
        int g_best = -1;
        double c_best = cos_group;
        for (std::size_t g = 0; g < units.size(); ++g) {
            const double c = counts[g] > 0 ? units[g].dot(nj) : -2.0;
            if (c >= c_best) {
                c_best = c;
                g_best = static_cast<int>(g);
            }
        }
        return g_best;
    }
    [[nodiscard]] std::ptrdiff_t left() const {
        return std::count_if(counts.begin(), counts.end(), [](int c) { return c > 0; });
    }
};

void group_normals(const std::vector<int>& members, const double* fn, double cos_group,
                   NormalGroups& groups) {
    std::vector<Vec3>& sums = groups.sums;
    std::vector<Vec3>& units = groups.units;
    std::vector<int>& counts = groups.counts;
    sums.clear();
    units.clear();
    counts.clear();
    for (const int j : members) {
        const CMap nj(fn + 3 * j);
        const int g = groups.nearest(nj, cos_group);
        if (g < 0) {
            sums.emplace_back(nj);
            units.emplace_back(nj);
            counts.push_back(1);
        } else {
            const auto gs = static_cast<std::size_t>(g);
            sums[gs] += nj;
            units[gs] = sums[gs].normalized();
            ++counts[gs];
        }
    }
    // Merge groups whose mean normals are within snap_group_deg of each other: the greedy pass
    // splits a curved patch whose normals span more than that angle (a sphere's cap), though
    // its halves' means are closer.
    for (bool merged = true; merged;) {
        merged = false;
        for (std::size_t g = 0; g < units.size() && !merged; ++g) {
            for (std::size_t h = g + 1; h < units.size() && !merged; ++h) {
                if (counts[g] == 0 || counts[h] == 0 || units[g].dot(units[h]) < cos_group) {
                    continue;
                }
                sums[g] += sums[h];
                units[g] = sums[g].normalized();
                counts[g] += counts[h];
                counts[h] = 0;
                merged = true;
            }
        }
    }
    // Drop the small groups (the blended normals of the last points near an edge), keep the 3
    // largest.
    const int min_count = std::max(6, static_cast<int>(0.1 * static_cast<double>(members.size())));
    for (int& c : counts) c = c < min_count ? 0 : c;
    while (groups.left() > 3) {
        auto smallest = counts.end();
        for (auto it = counts.begin(); it != counts.end(); ++it) {
            if (*it > 0 && (smallest == counts.end() || *it < *smallest)) smallest = it;
        }
        *smallest = 0;
    }
}

// The face plane of every surviving group with ≥ 3 members: every member to its nearest
// group; one pass accumulates the moments of each group's denoised positions (the plane) and
// of its input positions (their scatter about that plane: σ̂), relative to v_i / v⁰_i.
// Returns the largest σ̂ of the planes.
double fit_group_planes(const std::vector<int>& members, const NormalGroups& groups,
                        double cos_group, const double* v, const double* v0, const double* fn,
                        const Vec3& vi, const Vec3& v0i, std::vector<int>& slot,
                        std::vector<FacePlane>& planes) {
    struct Moments {
        int m = 0;
        Vec3 d = Vec3::Zero();
        Vec3 d0 = Vec3::Zero();
        Vec3 normals = Vec3::Zero();
        Sym3 S;
        Sym3 S0;
    };
    std::array<Moments, 3> mo{};  // the ≤ 3 surviving groups
    slot.assign(groups.counts.size(), -1);
    int used = 0;
    for (std::size_t g = 0; g < groups.counts.size(); ++g) {
        if (groups.counts[g] > 0) slot[g] = used++;
    }
    for (const int j : members) {
        const int g = groups.nearest(CMap(fn + 3 * j), cos_group);
        if (g < 0) continue;
        Moments& q = mo[static_cast<std::size_t>(slot[static_cast<std::size_t>(g)])];
        const Vec3 d = CMap(v + 3 * j) - vi;
        const Vec3 d0 = CMap(v0 + 3 * j) - v0i;
        ++q.m;
        q.d += d;
        q.d0 += d0;
        q.normals += CMap(fn + 3 * j);
        q.S.add(d);
        q.S0.add(d0);
    }
    planes.clear();
    double sigma = 0.0;
    for (int g = 0; g < used; ++g) {
        const Moments& q = mo[static_cast<std::size_t>(g)];
        if (q.m < 3) continue;
        const Vec3 mean = q.d / q.m;
        const Vec3 mean0 = q.d0 / q.m;
        const Eigen::Matrix3d C = q.S.matrix() / q.m - mean * mean.transpose();
        const Eigen::Matrix3d C0 = q.S0.matrix() / q.m - mean0 * mean0.transpose();
        Vec3 normal = eigen_decreasing(C).vectors.col(2);
        if (normal.dot(q.normals) < 0.0) normal = -normal;
        const Vec3 centroid = vi + mean;
        // Mean squared distance of the input points to the plane (Σ over the group of
        // (n·(v⁰_j − c))², c the plane's centroid).
        const double off = normal.dot(v0i + mean0 - centroid);
        sigma = std::max(sigma, std::sqrt(std::max(0.0, normal.dot(C0 * normal)) + off * off));
        planes.push_back(FacePlane{normal, normal.dot(centroid), centroid});
    }
    return sigma;
}

// Edge snapping (beyond §4.1; PointSetParams, docs/algorithms/pointset.md): near a feature,
// the faces are refitted from the points ≥ ~1.5 r away (whose normals the NVT leaves on the
// face) and the point is moved onto them, bounded by ε (Eq. 4.11). Reads the final positions
// and normals, writes row i of copies: thread-count independent. Moves out.V and N in place;
// returns the number of points moved.
int snap_edges(const Vertices& points, const KdTree& tree, const Csr& nb,
               const PointSetParams& params, PointSetResult& out, Vertices& N) {
    const int n = static_cast<int>(points.rows());
    const int* const items = nb.items.data();
    const int* const offsets = nb.offsets.data();
    const double cos_group = std::cos(params.snap_group_deg * M_PI / 180.0);
    const double support_radius = params.snap_support * out.radius;
    const std::vector<PointClass>& cls = out.classes;
    Vertices Vs = out.V;
    Vertices Ns = N;
    std::vector<int> moved(static_cast<std::size_t>(n), 0);
    const double* const v = out.V.data();
    const double* const fn = N.data();
    const double* const v0 = points.data();
    // A point is near a feature if its Ω_i holds an edge or corner point.
    std::vector<char> near_feature(static_cast<std::size_t>(n), 0);
    for (int i = 0; i < n; ++i) {
        for (int k = offsets[i]; k < offsets[i + 1]; ++k) {
            if (cls[static_cast<std::size_t>(items[k])] != PointClass::kFlat) {
                near_feature[static_cast<std::size_t>(i)] = 1;
                break;
            }
        }
    }
    // The reliable points: classified flat, with no feature point in their Ω_j.
    const auto reliable = [&](int j) {
        return cls[static_cast<std::size_t>(j)] == PointClass::kFlat &&
               near_feature[static_cast<std::size_t>(j)] == 0;
    };
    detail::parallel_for(n, params.threads, [&](int begin, int end) {
        std::vector<int> ball;
        std::vector<int> members;
        NormalGroups groups;
        std::vector<int> slot;  // group → index of its moments
        std::vector<FacePlane> planes;
        for (int i = begin; i < end; ++i) {
            if (near_feature[static_cast<std::size_t>(i)] == 0) continue;
            const CMap vi(v + 3 * i);
            const CMap v0i(v0 + 3 * i);
            tree.within(v0i, support_radius, ball);
            members.clear();
            for (const int j : ball) {
                if (reliable(j)) members.push_back(j);
            }
            group_normals(members, fn, cos_group, groups);
            if (groups.left() < 2) continue;  // one face (or none): nothing to sharpen
            const double sigma =
                fit_group_planes(members, groups, cos_group, v, v0, fn, vi, v0i, slot, planes);
            if (planes.size() < 2) continue;
            Vec3 x;
            int on_one = -1;
            if (!nearest_on_faces(vi, planes, params.snap_sigmas * sigma, &x, &on_one)) continue;
            // Eq. 4.11: the bound on the deviation from the input.
            if ((x - v0i).norm() > out.epsilon) continue;
            Vs.row(i) = x.transpose();
            if (on_one >= 0) Ns.row(i) = planes[static_cast<std::size_t>(on_one)].normal.transpose();
            moved[static_cast<std::size_t>(i)] = 1;
        }
    });
    out.V.swap(Vs);
    N.swap(Ns);
    return std::accumulate(moved.begin(), moved.end(), 0);
}

}  // namespace

PointSetResult pointset_denoise(const Vertices& points, const PointSetParams& params) {
    params.validate();
    const int n = static_cast<int>(points.rows());
    if (n < 8) throw AnalysisError("points: at least 8 are needed");
    if (!points.allFinite()) throw DataError("points: a coordinate is not finite");

    PointSetResult out;
    const auto t_setup = std::chrono::steady_clock::now();
    Setup st = setup(points, params, out);
    Vertices& N = st.N;
    out.seconds_setup = seconds_since(t_setup);

    out.V = points;
    out.classes.assign(static_cast<std::size_t>(n), PointClass::kFlat);
    const auto t_iter = std::chrono::steady_clock::now();
    const IterationConstants ic{std::cos(params.rho), out.radius * out.radius,
                               std::pow(2.0 * std::sin(params.rho / 2.0), 2),
                               out.radius * out.radius / 2.0};
    // Flat #P×3 row-major buffers, read through fixed-size maps; nothing is allocated inside
    // the iterations.
    Vertices Nf(n, 3);
    Vertices Vn(n, 3);
    Vertices edge_dir(n, 3);  // x1 of A_i: the edge direction at edge points
    std::vector<int> held(static_cast<std::size_t>(n), 0);
    for (int it = 0; it < params.iterations; ++it) {
        filter_normals(st.nb, N, params, ic, Nf);
        N.swap(Nf);
        classify_points(st.nb, out.V, N, params, ic, out.classes, edge_dir);
        update_vertices(points, st.nb, out.V, N, out.classes, edge_dir, params, ic, out.epsilon, Vn,
                        held);
        out.V.swap(Vn);
        ++out.iterations;
    }
    out.seconds_iterations = seconds_since(t_iter);
    if (params.snap_edges && params.iterations > 0) {
        const auto t_snap = std::chrono::steady_clock::now();
        out.snapped_points = snap_edges(points, st.tree, st.nb, params, out, N);
        out.seconds_snap = seconds_since(t_snap);
    }
    out.normals = N;
    out.held_points = std::accumulate(held.begin(), held.end(), 0);
    for (const PointClass c : out.classes) {
        out.corners += c == PointClass::kCorner ? 1 : 0;
        out.edges += c == PointClass::kEdge ? 1 : 0;
        out.flats += c == PointClass::kFlat ? 1 : 0;
    }
    return out;
}

}  // namespace octshape::mesh
