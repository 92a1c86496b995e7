// Closest points on triangles and the AABB tree, against independent brute force.

#include "octshape/error.h"
#include "octshape/mesh/closest_point.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <limits>
#include <random>

#include "mesh/mesh_fixtures.h"

namespace octshape::test {
namespace {

// Independent reference: the plane projection if it falls inside (barycentric test), else the
// best of the three segment projections.
double brute_distance(const Eigen::Vector3d& p,
                      const Eigen::Vector3d& a,
                      const Eigen::Vector3d& b,
                      const Eigen::Vector3d& c) {
    const Eigen::Vector3d n = (b - a).cross(c - a);
    double best = std::numeric_limits<double>::infinity();
    if (n.squaredNorm() > 0.0) {
        const Eigen::Vector3d q = p - n.dot(p - a) / n.squaredNorm() * n;
        const double u = (b - q).cross(c - q).dot(n);
        const double v = (c - q).cross(a - q).dot(n);
        const double w = (a - q).cross(b - q).dot(n);
        if (u >= 0 && v >= 0 && w >= 0) best = (p - q).norm();
    }
    for (const auto& [s, e] : {std::pair{a, b}, std::pair{b, c}, std::pair{c, a}}) {
        const Eigen::Vector3d d = e - s;
        const double t = std::clamp((p - s).dot(d) / d.squaredNorm(), 0.0, 1.0);
        best = std::min(best, (p - (s + t * d)).norm());
    }
    return best;
}

TEST(ClosestPoint, TriangleMatchesBruteForceInEveryVoronoiRegion) {
    std::mt19937 rng(3);
    std::uniform_real_distribution<double> u(-2.0, 2.0);
    const Eigen::Vector3d a(0, 0, 0);
    const Eigen::Vector3d b(1, 0.1, 0.2);
    const Eigen::Vector3d c(0.3, 0.9, -0.1);
    for (int k = 0; k < 20000; ++k) {
        const Eigen::Vector3d p(u(rng), u(rng), u(rng));
        const Eigen::Vector3d q = mesh::closest_point_on_triangle(p, a, b, c);
        EXPECT_NEAR((p - q).norm(), brute_distance(p, a, b, c), 1e-12);
        // q lies in the triangle's plane.
        EXPECT_NEAR((q - a).dot((b - a).cross(c - a).normalized()), 0.0, 1e-12);
    }
}

TEST(ClosestPoint, DegenerateTriangleFallsBackToItsEdges) {
    const Eigen::Vector3d a(0, 0, 0);
    const Eigen::Vector3d b(1, 0, 0);
    const Eigen::Vector3d c(2, 0, 0);
    const Eigen::Vector3d q = mesh::closest_point_on_triangle({1.5, 1, 0}, a, b, c);
    EXPECT_NEAR((q - Eigen::Vector3d(1.5, 0, 0)).norm(), 0.0, 1e-15);
}

TEST(ClosestPoint, TreeMatchesBruteForceOverAllTriangles) {
    const auto m = with_noise(icosphere(3), 0.03);
    const mesh::TriangleTree tree(m.V, m.F);
    std::mt19937 rng(5);
    std::uniform_real_distribution<double> u(-1.5, 1.5);
    for (int k = 0; k < 500; ++k) {
        const Eigen::Vector3d p(u(rng), u(rng), u(rng));
        double best = std::numeric_limits<double>::infinity();
        for (Eigen::Index f = 0; f < m.F.rows(); ++f) {
            best = std::min(best, brute_distance(p, m.V.row(m.F(f, 0)), m.V.row(m.F(f, 1)),
                                                 m.V.row(m.F(f, 2))));
        }
        const mesh::SurfaceHit hit = tree.closest(p);
        EXPECT_NEAR(hit.distance, best, 1e-12);
        EXPECT_NEAR((hit.point - p).norm(), hit.distance, 1e-12);
        ASSERT_GE(hit.face, 0);
        EXPECT_NEAR(brute_distance(p, m.V.row(m.F(hit.face, 0)), m.V.row(m.F(hit.face, 1)),
                                   m.V.row(m.F(hit.face, 2))),
                    best, 1e-12);
    }
}

TEST(ClosestPoint, EmptyOrInvalidReferenceIsRejected) {
    EXPECT_THROW(mesh::TriangleTree(mesh::Vertices(0, 3), mesh::Faces(0, 3)),
                 octshape::DataError);
    mesh::Faces bad(1, 3);
    bad << 0, 1, 5;
    EXPECT_THROW(mesh::TriangleTree(plane_grid(1).V, bad), octshape::DataError);
}

}  // namespace
}  // namespace octshape::test
