// E_v, MSAE, Q, flipped faces, volume: known answers.

#include "octshape/error.h"
#include "octshape/mesh/metrics.h"

#include <gtest/gtest.h>

#include <cmath>
#include <initializer_list>
#include <numbers>

#include "mesh/mesh_fixtures.h"

namespace octshape::test {
namespace {

TEST(Metrics, VertexErrorOfAMeshAgainstItselfIsZero) {
    for (const auto& m : noisy_family()) {
        const mesh::TriangleTree tree(m.V, m.F);
        EXPECT_EQ(mesh::vertex_error(m.V, m.F, tree), 0.0) << m.name;
    }
}

TEST(Metrics, VertexErrorOfAPlaneShiftedBySIsS) {
    // Every vertex is exactly s above its reference copy, which lies on the reference plane.
    const auto ref = plane_grid(10);
    for (const double s : {1e-3, 0.05, 0.7}) {
        mesh::Vertices V = ref.V;
        V.col(2).array() += s;
        EXPECT_NEAR(mesh::vertex_error(V, ref.F, mesh::TriangleTree(ref.V, ref.F)), s, 1e-15);
    }
}

TEST(Metrics, VertexErrorUsesTheSurfaceNotOnlyItsVertices) {
    // One vertex at the middle of a reference triangle, height 0: distance 0, though the
    // nearest reference vertex is far away.
    mesh::Vertices R(3, 3);
    R << 0, 0, 0, 10, 0, 0, 0, 10, 0;
    mesh::Faces F(1, 3);
    F << 0, 1, 2;
    mesh::Vertices V(3, 3);
    V << 3, 3, 0, 4, 3, 0, 3, 4, 0;
    EXPECT_EQ(mesh::vertex_error(V, F, mesh::TriangleTree(R, F)), 0.0);
}

TEST(Metrics, QualityOfEquilateralIsOneOverRootThree) {
    mesh::Vertices V(3, 3);
    V << 0, 0, 0, 1, 0, 0, 0.5, std::sqrt(3.0) / 2.0, 0;
    mesh::Faces F(1, 3);
    F << 0, 1, 2;
    EXPECT_NEAR(mesh::mesh_quality(V, F), 1.0 / std::sqrt(3.0), 1e-15);
    // Right isosceles: circumradius = hypotenuse / 2 = √2/2, shortest edge 1.
    V.row(2) << 0, 1, 0;
    EXPECT_NEAR(mesh::mesh_quality(V, F), std::sqrt(2.0) / 2.0, 1e-15);
    V.row(2) << 2, 0, 0;  // degenerate
    EXPECT_TRUE(std::isinf(mesh::mesh_quality(V, F)));
}

TEST(Metrics, RotatingEveryNormalByAlphaGivesMsaeAlpha) {
    // All normals of the grid are +z; a rotation about x turns each of them by exactly α.
    const auto ref = plane_grid(5);
    for (const double deg : {0.5, 10.0, 75.0, 150.0}) {
        const Eigen::Matrix3d R =
            Eigen::AngleAxisd(deg * std::numbers::pi / 180.0, Eigen::Vector3d::UnitX())
                .toRotationMatrix();
        const mesh::Vertices V = ref.V * R.transpose();
        EXPECT_NEAR(mesh::mean_angle_error_deg(V, ref.F, ref.V, ref.F), deg, 1e-9);
    }
}

TEST(Metrics, MirroredPlaneHasEveryFaceFlipped) {
    const auto ref = plane_grid(6);
    mesh::Vertices V = ref.V;
    V.col(0) *= -1.0;  // mirror: orientation reverses
    EXPECT_EQ(mesh::flipped_faces(V, ref.F, ref.V, ref.F), ref.F.rows());
    EXPECT_NEAR(mesh::mean_angle_error_deg(V, ref.F, ref.V, ref.F), 180.0, 1e-9);
    EXPECT_EQ(mesh::flipped_faces(ref.V, ref.F, ref.V, ref.F), 0);
}

// Pushing an interior vertex of the plane 1.5 grid steps sideways, past its neighbour, turns
// some of its faces over (their normals point down); a vertex far away does the same to its
// own faces. Flipped in the input only = fixed, in the output only = created, in both = kept.
TEST(Metrics, FlipTransitionsSortFacesByWhereTheyFlipped) {
    const int n = 8;
    const auto ref = plane_grid(n);
    const double h = 1.0 / n;
    const auto pushed = [&](std::initializer_list<int> vertices) {
        mesh::Vertices V = ref.V;
        for (const int v : vertices) V(v, 0) += 1.5 * h;
        return V;
    };
    const int a = 2 * (n + 1) + 2;  // vertex (2, 2)
    const int b = 6 * (n + 1) + 5;  // vertex (5, 6): no face shared with a's
    const int flips_a = mesh::flipped_faces(pushed({a}), ref.F, ref.V, ref.F);
    const int flips_b = mesh::flipped_faces(pushed({b}), ref.F, ref.V, ref.F);
    ASSERT_GT(flips_a, 0);
    ASSERT_GT(flips_b, 0);

    const auto moved = mesh::flip_transitions(pushed({b}), pushed({a}), ref.V, ref.F);
    EXPECT_EQ(moved.input, flips_a);
    EXPECT_EQ(moved.output, flips_b);
    EXPECT_EQ(moved.created, flips_b);
    EXPECT_EQ(moved.kept, 0);
    EXPECT_EQ(moved.fixed, flips_a);

    const auto added = mesh::flip_transitions(pushed({a, b}), pushed({a}), ref.V, ref.F);
    EXPECT_EQ(added.output, flips_a + flips_b);
    EXPECT_EQ(added.created, flips_b);
    EXPECT_EQ(added.kept, flips_a);
    EXPECT_EQ(added.fixed, 0);

    const auto same = mesh::flip_transitions(ref.V, ref.V, ref.V, ref.F);
    EXPECT_EQ(same.input + same.output + same.created + same.kept + same.fixed, 0);
    const auto other = plane_grid(n + 1);
    EXPECT_THROW((void)mesh::flip_transitions(other.V, ref.V, ref.V, ref.F),
                 octshape::DataError);
}

TEST(Metrics, VolumeOfTheCubeAndVolumeChange) {
    const auto c = cube(3);
    EXPECT_NEAR(mesh::signed_volume(c.V, c.F), 8.0, 1e-12);
    const mesh::Vertices bigger = c.V * 1.1;
    const auto cmp = mesh::compare_meshes(bigger, c.F, c.V, c.F);
    EXPECT_NEAR(cmp.volume_change, 1.1 * 1.1 * 1.1 - 1.0, 1e-12);
    EXPECT_TRUE(cmp.closed);
    // Scaling about the centre: every vertex moves radially, no normal changes.
    EXPECT_NEAR(cmp.msae_deg, 0.0, 1e-9);
    EXPECT_EQ(cmp.flipped_faces, 0);
    EXPECT_FALSE(mesh::compare_meshes(plane_grid(2).V, plane_grid(2).F, plane_grid(2).V,
                                      plane_grid(2).F)
                     .closed);
}

TEST(Metrics, DifferentTriangulationsAreRejectedForFaceMeasures) {
    const auto a = plane_grid(3);
    const auto b = plane_grid(4);
    EXPECT_THROW((void)mesh::mean_angle_error_deg(a.V, a.F, b.V, b.F), octshape::DataError);
    EXPECT_THROW((void)mesh::compare_meshes(a.V, a.F, b.V, b.F), octshape::DataError);
}

}  // namespace
}  // namespace octshape::test
