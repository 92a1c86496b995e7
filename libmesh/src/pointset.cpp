#include "octshape/mesh/pointset.h"

#include <algorithm>
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

namespace octshape::mesh {
namespace {

constexpr int kLeafSize = 8;
// Neighbours averaged for the point spacing: the 1-ring of a regular triangulation.
constexpr int kSpacingNeighbours = 6;

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

Eigen3 eigen_decreasing(const Eigen::Matrix3d& M) {
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(M);
    Eigen3 out;
    for (int k = 0; k < 3; ++k) {
        out.values(k) = solver.eigenvalues()(2 - k);
        out.vectors.col(k) = solver.eigenvectors().col(2 - k);
    }
    return out;
}

}  // namespace

// ---------------------------------------------------------------- k-d tree

KdTree::KdTree(const Vertices& points) : P_(points) {
    if (!P_.allFinite()) throw std::invalid_argument("points: a coordinate is not finite");
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
    if (nodes_.empty() || !(radius >= 0.0)) return out;
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
    std::sort(out.begin(), out.end());
    return out;
}

// ---------------------------------------------------------------- neighbourhoods, normals

double mean_point_spacing(const Vertices& points, const KdTree& tree) {
    const int n = static_cast<int>(points.rows());
    if (n < kSpacingNeighbours + 1) return 0.0;
    double sum = 0.0;
    for (int i = 0; i < n; ++i) {
        const Eigen::Vector3d p = points.row(i).transpose();
        // The nearest k + 1 include i itself (distance 0) unless duplicates exist.
        const std::vector<int> near = tree.nearest(p, kSpacingNeighbours + 1);
        double s = 0.0;
        for (const int j : near) s += (points.row(j).transpose() - p).norm();
        sum += s / static_cast<double>(near.size() - 1);
    }
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

Vertices pca_normals(const Vertices& points, const Csr& nb) {
    const int n = static_cast<int>(points.rows());
    Vertices N(n, 3);
    for (int i = 0; i < n; ++i) {
        Eigen::Vector3d mean = Eigen::Vector3d::Zero();
        for (int k = nb.begin(i); k < nb.end(i); ++k) mean += points.row(nb.item(k)).transpose();
        mean /= nb.size(i);
        Eigen::Matrix3d C = Eigen::Matrix3d::Zero();
        for (int k = nb.begin(i); k < nb.end(i); ++k) {
            const Eigen::Vector3d d = points.row(nb.item(k)).transpose() - mean;
            C += d * d.transpose();
        }
        N.row(i) = eigen_decreasing(C).vectors.col(2).transpose();
    }
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
    using Item = std::tuple<double, int, int>;
    std::priority_queue<Item, std::vector<Item>, std::greater<>> queue;
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
                queue.emplace(1.0 - std::abs(N.row(i).dot(N.row(j))), j, i);
            }
        }
    }
    return N;
}

// ---------------------------------------------------------------- denoiser

void PointSetParams::validate() const {
    const auto bad = [](const std::string& what) { throw std::invalid_argument(what); };
    if (!(tau > 0.0 && tau < 1.0)) bad("tau must be in (0, 1)");
    if (!(rho > 0.0 && rho <= M_PI)) bad("rho must be in (0, pi] radians");
    if (iterations < 0) bad("iterations must be >= 0");
    if (!(damping >= 0.0) || !std::isfinite(damping)) bad("damping must be finite and >= 0");
    if (!(lambda > 0.0 && lambda <= 1.0)) bad("lambda must be in (0, 1]");
    if (radius && !(*radius > 0.0 && std::isfinite(*radius))) bad("radius must be > 0");
    if (epsilon && !(*epsilon >= 0.0 && std::isfinite(*epsilon))) bad("epsilon must be >= 0");
    if (min_neighbours < 4) bad("min_neighbours must be >= 4");
    if (threads < 1) bad("threads must be >= 1");
}

PointSetResult pointset_denoise(const Vertices& points, const PointSetParams& params) {
    params.validate();
    const int n = static_cast<int>(points.rows());
    if (n < 8) throw std::invalid_argument("points: at least 8 are needed");
    if (!points.allFinite()) throw std::invalid_argument("points: a coordinate is not finite");

    PointSetResult out;
    const auto t_setup = std::chrono::steady_clock::now();
    const KdTree tree(points);
    out.mean_spacing = mean_point_spacing(points, tree);
    out.radius = params.radius ? *params.radius : 2.0 * out.mean_spacing;  // §4.2.1
    if (!(out.radius > 0.0)) throw std::invalid_argument("points: all points coincide");
    out.epsilon = params.epsilon ? *params.epsilon : out.radius;
    const Csr nb = point_neighbourhoods(points, tree, out.radius, params.min_neighbours,
                                        params.threads);
    out.mean_neighbourhood = static_cast<double>(nb.items.size()) / n;
    Vertices N = pca_normals(points, nb);
    out.seconds_setup = seconds_since(t_setup);

    out.V = points;
    out.classes.assign(static_cast<std::size_t>(n), PointClass::kFlat);
    const auto t_iter = std::chrono::steady_clock::now();
    const double cos_rho = std::cos(params.rho);
    const double r2 = out.radius * out.radius;
    const double c2 = std::pow(2.0 * std::sin(params.rho / 2.0), 2);
    const double flat_trace = r2 / 2.0;  // trace of A_i for a flat disc of radius r
    Vertices Nf(n, 3);
    Vertices Vn(n, 3);
    Vertices edge_dir(n, 3);  // x1 of A_i: the edge direction at edge points
    std::vector<int> held(static_cast<std::size_t>(n), 0);
    for (int it = 0; it < params.iterations; ++it) {
        const Vertices& V = out.V;
        // (1) Normal filtering, Eq. 4.1–4.6.
        detail::parallel_for(n, params.threads, [&](int begin, int end) {
            for (int i = begin; i < end; ++i) {
                const Eigen::Vector3d ni = N.row(i).transpose();
                Eigen::Matrix3d C = Eigen::Matrix3d::Zero();
                int count = 0;
                for (int k = nb.begin(i); k < nb.end(i); ++k) {
                    const Eigen::Vector3d nj = N.row(nb.item(k)).transpose();
                    if (ni.dot(nj) < cos_rho) continue;  // Eq. 4.2: w_ij = 0
                    C += nj * nj.transpose();
                    ++count;
                }
                C /= count;  // count ≥ 1: n_i itself
                const Eigen3 e = eigen_decreasing(C);
                // Binary optimisation (§4.1.1): λ̃ = (1,1,1), (1,1,0) or (1,0,0).
                const int kept = e.values(2) >= params.tau ? 3 : e.values(1) >= params.tau ? 2 : 1;
                Eigen::Vector3d filtered = params.damping * ni;  // Eq. 4.6
                for (int m = 0; m < kept; ++m) {
                    filtered += e.vectors.col(m).dot(ni) * e.vectors.col(m);
                }
                const double len = filtered.norm();
                Nf.row(i) = (len > 0.0 ? (filtered / len) : ni).transpose();
            }
        });
        N = Nf;
        // (2) Classification, Eq. 4.7–4.10.
        detail::parallel_for(n, params.threads, [&](int begin, int end) {
            for (int i = begin; i < end; ++i) {
                const Eigen::Vector3d ni = N.row(i).transpose();
                Eigen::Vector3d centre = Eigen::Vector3d::Zero();
                int count = 0;
                for (int k = nb.begin(i); k < nb.end(i); ++k) {
                    const int j = nb.item(k);
                    if (ni.dot(N.row(j).transpose()) < cos_rho) continue;  // Eq. 4.8
                    centre += V.row(j).transpose();
                    ++count;
                }
                centre /= count;  // Eq. 4.8: v_c
                Eigen::Matrix3d A = Eigen::Matrix3d::Zero();
                for (int k = nb.begin(i); k < nb.end(i); ++k) {
                    const int j = nb.item(k);
                    if (ni.dot(N.row(j).transpose()) < cos_rho) continue;
                    const Eigen::Vector3d d = V.row(j).transpose() - centre;
                    A += d * d.transpose();
                }
                A /= count;  // Eq. 4.7
                const Eigen3 a = eigen_decreasing(A);
                const Eigen::Vector3d s = a.values / flat_trace;
                PointClass cls = PointClass::kCorner;  // Eq. 4.10: all ≥ τ or all < τ
                if (s(0) >= params.tau && s(1) >= params.tau && s(2) < params.tau) {
                    cls = PointClass::kFlat;
                } else if (s(0) >= params.tau && s(1) < params.tau) {
                    cls = PointClass::kEdge;
                }
                out.classes[static_cast<std::size_t>(i)] = cls;
                edge_dir.row(i) = a.vectors.col(0).transpose();
            }
        });
        // (3) Vertex update, Eq. 4.11–4.17.
        detail::parallel_for(n, params.threads, [&](int begin, int end) {
            for (int i = begin; i < end; ++i) {
                const Eigen::Vector3d ni = N.row(i).transpose();
                const Eigen::Vector3d vi = V.row(i).transpose();
                const PointClass cls = out.classes[static_cast<std::size_t>(i)];
                // A small Tikhonov term μ|v − v_i|² keeps the position unchanged along
                // directions the quadric does not constrain (a rank-deficient Σ N_j).
                const double mu = 1e-3 * nb.size(i);
                Eigen::Vector3d candidate = vi;
                if (cls == PointClass::kCorner) {  // Eq. 4.13
                    Eigen::Matrix3d M = mu * Eigen::Matrix3d::Identity();
                    Eigen::Vector3d b = mu * vi;
                    for (int k = nb.begin(i); k < nb.end(i); ++k) {
                        const int j = nb.item(k);
                        const Eigen::Vector3d nj = N.row(j).transpose();
                        const Eigen::Matrix3d Nj = nj * nj.transpose();
                        M += Nj;
                        b += Nj * V.row(j).transpose();
                    }
                    candidate = M.ldlt().solve(b);
                } else if (cls == PointClass::kEdge) {  // Eq. 4.14–4.15
                    const Eigen::Vector3d x1 = edge_dir.row(i).transpose();
                    const Eigen::Matrix3d X = x1 * x1.transpose();
                    Eigen::Matrix3d M = X + mu * Eigen::Matrix3d::Identity();
                    Eigen::Vector3d b = X * vi + mu * vi;
                    for (int k = nb.begin(i); k < nb.end(i); ++k) {
                        const int j = nb.item(k);
                        const Eigen::Vector3d vj = V.row(j).transpose();
                        const Eigen::Vector3d nj = N.row(j).transpose();
                        const Eigen::Vector3d vp = vj - (vj - vi).dot(x1) * x1;
                        const Eigen::Vector3d np = nj - nj.dot(x1) * x1;
                        const Eigen::Matrix3d Nj = np * np.transpose();
                        M += Nj;
                        b += Nj * vp;
                    }
                    candidate = M.ldlt().solve(b);
                } else {  // Eq. 4.16–4.17
                    double wsum = 0.0;
                    double step = 0.0;
                    for (int k = nb.begin(i); k < nb.end(i); ++k) {
                        const int j = nb.item(k);
                        const Eigen::Vector3d vj = V.row(j).transpose();
                        const Eigen::Vector3d nj = N.row(j).transpose();
                        // Eq. 4.17. The thesis divides |ñ_i − ñ_j|² by r², a length²; on unit
                        // normals the width must be dimensionless: we use the chord of the
                        // angle threshold, c = 2 sin(ρ/2) (docs/algorithms/pointset.md).
                        const double w = std::exp(-16.0 * (ni - nj).squaredNorm() / c2) *
                                         std::exp(-4.0 * (vj - vi).squaredNorm() / r2);
                        wsum += w;
                        step += w * nj.dot(vj - vi);
                    }
                    candidate = vi + params.lambda * step / wsum * ni;
                }
                // Eq. 4.11: the bound on the deviation from the input.
                if ((candidate - points.row(i).transpose()).norm() > out.epsilon ||
                    !candidate.allFinite()) {
                    candidate = vi;
                    ++held[static_cast<std::size_t>(i)];
                }
                Vn.row(i) = candidate.transpose();
            }
        });
        out.V = Vn;
        ++out.iterations;
    }
    out.seconds_iterations = seconds_since(t_iter);
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
