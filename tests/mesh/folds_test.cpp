// Fold-over repair (folds.h): what counts as a fold, what the repair moves and what it keeps.

#include "octshape/error.h"
#include "octshape/mesh/folds.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <stdexcept>
#include <vector>

#include "mesh/mesh_fixtures.h"
#include "octshape/mesh/metrics.h"

namespace octshape::test {
namespace {

// plane_grid(n) with its right half (x > 1/2) folded back over the left about the line
// x = 1/2, leaving an interior angle of `angle_deg` between the halves: the halves' normals
// are 180° − angle apart.
TestMesh wedge(int n, double angle_deg) {
    TestMesh m = plane_grid(n);
    const double a = angle_deg * std::numbers::pi / 180.0;
    for (Eigen::Index v = 0; v < m.V.rows(); ++v) {
        const double d = m.V(v, 0) - 0.5;
        if (d > 0.0) {
            m.V(v, 0) = 0.5 - d * std::cos(a);
            m.V(v, 2) = d * std::sin(a);
        }
    }
    return m;
}

// plane_grid(n)'s vertices with vertex (2, 2) pushed 1.5 grid steps along x.
mesh::Vertices pushed_grid(int n) {
    mesh::Vertices V = plane_grid(n).V;
    V.row(2 * (n + 1) + 2) += Eigen::RowVector3d(1.5 / n, 0.0, 0.0);
    return V;
}

TEST(Folds, APushedVertexFoldsAndIsRepairedOntoItsGridPoint) {
    // Vertex (2, 2) pushed 1.5 grid steps along x crosses its neighbour's edges: some of its
    // faces turn over (normal −z against +z around them). Its 1-ring centroid on the regular
    // grid is the vertex's own grid point, so one round restores the plane exactly.
    const int n = 8;
    const auto ref = plane_grid(n);
    mesh::Vertices V = pushed_grid(n);
    ASSERT_GT(mesh::flipped_faces(V, ref.F, ref.V, ref.F), 0);
    const int folds = mesh::count_folds(V, ref.F);
    ASSERT_GT(folds, 0);
    const auto r = mesh::repair_folds(V, ref.F, {});
    EXPECT_EQ(r.folds_found, folds);
    EXPECT_EQ(r.folds_left, 0);
    EXPECT_EQ(r.rounds, 1);
    EXPECT_EQ(r.vertices_moved, 1);
    EXPECT_LT((V - ref.V).cwiseAbs().maxCoeff(), 1e-15);
    EXPECT_EQ(mesh::flipped_faces(V, ref.F, ref.V, ref.F), 0);
}

TEST(Folds, AFixedApexStaysAndItsFoldIsReported) {
    const int n = 8;
    const auto ref = plane_grid(n);
    mesh::Vertices V = pushed_grid(n);
    const mesh::Vertices before = V;
    std::vector<std::uint8_t> fixed(static_cast<std::size_t>(V.rows()), 0);
    fixed[static_cast<std::size_t>(2 * (n + 1) + 2)] = 1;
    const auto r = mesh::repair_folds(V, ref.F, fixed);
    EXPECT_GT(r.folds_left, 0);
    EXPECT_EQ(r.vertices_moved, 0);
    EXPECT_EQ(V, before);
}

TEST(Folds, SharpFeaturesAreNotFolds) {
    // The cube's 90° edges and a 30° wedge (normals 150° apart, n_a · n_b = −0.87 > −0.9)
    // are features: nothing is counted and nothing moves.
    for (const auto& m : {cube(4), wedge(8, 30.0)}) {
        EXPECT_EQ(mesh::count_folds(m.V, m.F), 0) << m.name;
        mesh::Vertices V = m.V;
        const auto r = mesh::repair_folds(V, m.F, {});
        EXPECT_EQ(r.folds_found, 0);
        EXPECT_EQ(r.rounds, 0);
        EXPECT_EQ(V, m.V);
    }
}

TEST(Folds, AWedgeSharperThan26DegreesCountsAsFolded) {
    // The documented limit: at 20° (normals 160° apart, −0.94) every ridge edge is a fold.
    const int n = 8;
    const auto m = wedge(n, 20.0);
    EXPECT_EQ(mesh::count_folds(m.V, m.F), n);
    EXPECT_EQ(mesh::count_folds(m.V, m.F, 0.95), 0);
}

TEST(Folds, RepairCommutesWithARigidMotion) {
    const int n = 8;
    const auto ref = plane_grid(n);
    mesh::Vertices V = pushed_grid(n) + (with_noise(ref, 0.02).V - ref.V);
    V.row(5 * (n + 1) + 6) -= Eigen::RowVector3d(0.0, 1.4 / n, 0.0);
    const Eigen::Matrix3d R =
        Eigen::AngleAxisd(0.7, Eigen::Vector3d(1.0, 2.0, -0.5).normalized()).toRotationMatrix();
    const Eigen::RowVector3d t(0.3, -2.0, 5.0);
    mesh::Vertices moved = (V * R.transpose()).rowwise() + t;
    const auto a = mesh::repair_folds(V, ref.F, {});
    const auto b = mesh::repair_folds(moved, ref.F, {});
    ASSERT_GT(a.folds_found, 0);
    EXPECT_EQ(a.folds_found, b.folds_found);
    EXPECT_EQ(a.vertices_moved, b.vertices_moved);
    EXPECT_EQ(a.folds_left, 0);
    // Centroid moves and rotations commute; what is left is rounding (coordinates ~5).
    const mesh::Vertices expected = (V * R.transpose()).rowwise() + t;
    EXPECT_LT((moved - expected).cwiseAbs().maxCoeff(), 1e-12);
}

TEST(Folds, BadParametersAndSizesThrow) {
    const auto m = plane_grid(2);
    mesh::Vertices V = m.V;
    mesh::FoldRepairParams p;
    p.cos_fold = 0.0;
    EXPECT_THROW((void)mesh::repair_folds(V, m.F, {}, p), octshape::UsageError);
    p = {};
    p.max_rounds = -1;
    EXPECT_THROW((void)mesh::repair_folds(V, m.F, {}, p), octshape::UsageError);
    EXPECT_THROW((void)mesh::repair_folds(V, m.F, std::vector<std::uint8_t>(2, 0)),
                 octshape::DataError);
}

}  // namespace
}  // namespace octshape::test
