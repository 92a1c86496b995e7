// E_v, MSAE, Q, flipped faces, volume: known answers.

#include "octshape/mesh/metrics.h"

#include <gtest/gtest.h>

#include <cmath>
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
    EXPECT_THROW((void)mesh::mean_angle_error_deg(a.V, a.F, b.V, b.F), std::invalid_argument);
    EXPECT_THROW((void)mesh::compare_meshes(a.V, a.F, b.V, b.F), std::invalid_argument);
}

}  // namespace
}  // namespace octshape::test
