// Mesh sections (mesh/section.h): a plane through a closed polyhedron cuts it in closed
// polygons lying in the plane, whose length is known on paper.

#include "octshape/mesh/section.h"

#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <vector>

#include "mesh/mesh_fixtures.h"
#include "octshape/error.h"

namespace octshape::test {
namespace {

TEST(MeshSection, PlaneThroughACubeIsItsRectangleExactly) {
    // The cube [-1, 1]^3 (flat sides, so the section is exact) cut by x + y / 2 = 0.3, a plane
    // parallel to z that meets no vertex (the 4 x 4 grid's coordinates are multiples of 0.5):
    // the section is the rectangle of sides 2 sqrt(1.25) (across the top and bottom) and 2.
    const TestMesh c = cube(4);
    const Eigen::Vector3d n(1.0, 0.5, 0.0);
    const auto segs = mesh::plane_section(c.V, c.F, n, 0.3);
    double length = 0.0;
    std::map<std::array<long, 3>, int> ends;  // endpoints rounded to 1e-9: each shared by two
    for (const auto& s : segs) {
        EXPECT_NEAR(n.dot(s.a), 0.3, 1e-15);
        EXPECT_NEAR(n.dot(s.b), 0.3, 1e-15);
        length += (s.b - s.a).norm();
        for (const Eigen::Vector3d& p : {s.a, s.b}) {
            ++ends[{std::lround(p.x() * 1e9), std::lround(p.y() * 1e9), std::lround(p.z() * 1e9)}];
        }
    }
    EXPECT_NEAR(length, 2.0 * (2.0 * std::sqrt(1.25) + 2.0), 1e-12);
    for (const auto& [p, count] : ends) EXPECT_EQ(count, 2) << "an open end: not a closed polygon";
}

TEST(MeshSection, ZeroCountsAsPositiveAndTheValuesMustMatchTheVertices) {
    mesh::Vertices V(3, 3);
    V << 0, 0, 0, 1, 0, 0, 0, 1, 0;
    mesh::Faces F(1, 3);
    F << 0, 1, 2;
    // Vertex 0 on the level: with both others negative it is the positive side (one segment
    // from vertex 0 to vertex 0); with both others positive there is no crossing.
    const std::vector<double> below{0.0, -1.0, -1.0};
    const auto one = mesh::zero_level_segments(V, F, below);
    ASSERT_EQ(one.size(), 1u);
    EXPECT_EQ(one[0].a, Eigen::Vector3d::Zero());
    EXPECT_EQ(one[0].b, Eigen::Vector3d::Zero());
    const std::vector<double> above{0.0, 1.0, 1.0};
    EXPECT_TRUE(mesh::zero_level_segments(V, F, above).empty());
    const std::vector<double> short_values{0.0, 1.0};
    EXPECT_THROW((void)mesh::zero_level_segments(V, F, short_values), UsageError);
}

}  // namespace
}  // namespace octshape::test
