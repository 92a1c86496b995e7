#include "octshape/mesh/closest_point.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "octshape/error.h"

namespace octshape::mesh {

Eigen::Vector3d closest_point_on_triangle(const Eigen::Vector3d& p,
                                          const Eigen::Vector3d& a,
                                          const Eigen::Vector3d& b,
                                          const Eigen::Vector3d& c) {
    // Voronoi regions of the vertices, then of the edges, else the interior.
    const Eigen::Vector3d ab = b - a;
    const Eigen::Vector3d ac = c - a;
    const Eigen::Vector3d ap = p - a;
    const double d1 = ab.dot(ap);
    const double d2 = ac.dot(ap);
    if (d1 <= 0.0 && d2 <= 0.0) return a;
    const Eigen::Vector3d bp = p - b;
    const double d3 = ab.dot(bp);
    const double d4 = ac.dot(bp);
    if (d3 >= 0.0 && d4 <= d3) return b;
    const double vc = d1 * d4 - d3 * d2;
    if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0) {
        const double denom = d1 - d3;
        return denom > 0.0 ? Eigen::Vector3d(a + (d1 / denom) * ab) : a;
    }
    const Eigen::Vector3d cp = p - c;
    const double d5 = ab.dot(cp);
    const double d6 = ac.dot(cp);
    if (d6 >= 0.0 && d5 <= d6) return c;
    const double vb = d5 * d2 - d1 * d6;
    if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0) {
        const double denom = d2 - d6;
        return denom > 0.0 ? Eigen::Vector3d(a + (d2 / denom) * ac) : a;
    }
    const double va = d3 * d6 - d5 * d4;
    if (va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0) {
        const double denom = (d4 - d3) + (d5 - d6);
        return denom > 0.0 ? Eigen::Vector3d(b + ((d4 - d3) / denom) * (c - b)) : b;
    }
    const double sum = va + vb + vc;
    if (!(sum > 0.0)) {
        // Degenerate (collinear) triangle that fell through the tests above: best of its edges.
        Eigen::Vector3d best = a;
        double best_d = (p - a).squaredNorm();
        for (const auto& [s, e] : {std::pair{a, b}, std::pair{b, c}, std::pair{c, a}}) {
            const Eigen::Vector3d d = e - s;
            const double len2 = d.squaredNorm();
            const double t = len2 > 0.0 ? std::clamp((p - s).dot(d) / len2, 0.0, 1.0) : 0.0;
            const Eigen::Vector3d q = s + t * d;
            if ((p - q).squaredNorm() < best_d) {
                best_d = (p - q).squaredNorm();
                best = q;
            }
        }
        return best;
    }
    const double v = vb / sum;
    const double w = vc / sum;
    return a + v * ab + w * ac;
}

TriangleTree::TriangleTree(const Vertices& V, const Faces& F) : V_(V), F_(F) {
    validate_mesh(V_, F_);
    if (F_.rows() == 0) throw DataError("F: the reference surface has no triangle");
    const auto m = static_cast<int>(F_.rows());
    order_.resize(static_cast<std::size_t>(m));
    std::vector<Eigen::Vector3d> centres(static_cast<std::size_t>(m));
    for (int f = 0; f < m; ++f) {
        order_[static_cast<std::size_t>(f)] = f;
        centres[static_cast<std::size_t>(f)] =
            (V_.row(F_(f, 0)) + V_.row(F_(f, 1)) + V_.row(F_(f, 2))).transpose() / 3.0;
    }
    nodes_.reserve(static_cast<std::size_t>(m));
    nodes_.emplace_back();
    build(0, 0, m, centres);
}

// Fills node `index` over order_[first, first+count): its box, and either a leaf or a median
// split of the triangle centres along the longest box axis into two new child nodes.
void TriangleTree::build(int index,
                         int first,
                         int count,
                         std::vector<Eigen::Vector3d>& centres) {
    Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
    Eigen::Vector3d hi = -lo;
    for (int k = first; k < first + count; ++k) {
        const int f = order_[static_cast<std::size_t>(k)];
        for (int j = 0; j < 3; ++j) {
            lo = lo.cwiseMin(V_.row(F_(f, j)).transpose());
            hi = hi.cwiseMax(V_.row(F_(f, j)).transpose());
        }
    }
    nodes_[static_cast<std::size_t>(index)].lo = lo;
    nodes_[static_cast<std::size_t>(index)].hi = hi;
    constexpr int kLeafSize = 4;
    if (count <= kLeafSize) {
        nodes_[static_cast<std::size_t>(index)].first = first;
        nodes_[static_cast<std::size_t>(index)].count = count;
        return;
    }
    int axis = 0;
    (hi - lo).maxCoeff(&axis);
    const int half = count / 2;
    const auto begin = order_.begin() + first;
    std::nth_element(begin, begin + half, begin + count, [&](int x, int y) {
        return centres[static_cast<std::size_t>(x)](axis) <
               centres[static_cast<std::size_t>(y)](axis);
    });
    const int left = static_cast<int>(nodes_.size());
    nodes_.emplace_back();
    nodes_.emplace_back();
    nodes_[static_cast<std::size_t>(index)].first = left;
    nodes_[static_cast<std::size_t>(index)].count = 0;
    build(left, first, half, centres);
    build(left + 1, first + half, count - half, centres);
}

namespace {

double box_distance2(const Eigen::Vector3d& p, const Eigen::Vector3d& lo, const Eigen::Vector3d& hi) {
    const Eigen::Vector3d d = (lo - p).cwiseMax(p - hi).cwiseMax(0.0);
    return d.squaredNorm();
}

}  // namespace

SurfaceHit TriangleTree::closest(const Eigen::Vector3d& p) const {
    SurfaceHit best;
    double best_d2 = std::numeric_limits<double>::infinity();
    int stack[128];
    int top = 0;
    stack[top++] = 0;
    while (top > 0) {
        const Node& node = nodes_[static_cast<std::size_t>(stack[--top])];
        if (box_distance2(p, node.lo, node.hi) >= best_d2) continue;
        if (node.count > 0) {
            for (int k = node.first; k < node.first + node.count; ++k) {
                const int f = order_[static_cast<std::size_t>(k)];
                const Eigen::Vector3d q = closest_point_on_triangle(
                    p, V_.row(F_(f, 0)), V_.row(F_(f, 1)), V_.row(F_(f, 2)));
                const double d2 = (p - q).squaredNorm();
                if (d2 < best_d2) {
                    best_d2 = d2;
                    best.point = q;
                    best.face = f;
                }
            }
            continue;
        }
        // Visit the nearer child first: push it last.
        const Node& l = nodes_[static_cast<std::size_t>(node.first)];
        const Node& r = nodes_[static_cast<std::size_t>(node.first) + 1];
        const double dl = box_distance2(p, l.lo, l.hi);
        const double dr = box_distance2(p, r.lo, r.hi);
        if (dl <= dr) {
            stack[top++] = node.first + 1;
            stack[top++] = node.first;
        } else {
            stack[top++] = node.first;
            stack[top++] = node.first + 1;
        }
    }
    best.distance = std::sqrt(best_d2);
    return best;
}

}  // namespace octshape::mesh
