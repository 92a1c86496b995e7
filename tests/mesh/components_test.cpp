// libmesh connectivity edits: connected components, compaction, largest component, orientation.

#include "octshape/mesh/components.h"

#include <gtest/gtest.h>

#include <cstdint>
#include <set>
#include <vector>

#include "mesh/mesh_fixtures.h"
#include "octshape/error.h"

namespace octshape::test {
namespace {

// Two disjoint plane grids in one mesh: `a` (n_a × n_a squares) first, then `b` shifted by
// (10, 0, z_b); b's vertex indices follow a's. Interleave: the faces alternate between the
// grids (as far as both have faces) so a component is not a contiguous block of faces.
TestMesh two_grids(int n_a, int n_b, double z_b = 0.0, bool interleave = false) {
    const TestMesh a = plane_grid(n_a);
    TestMesh b = plane_grid(n_b);
    b.V.col(0).array() += 10.0;
    b.V.col(2).array() += z_b;
    b.F.array() += static_cast<int>(a.V.rows());
    TestMesh m{"two", mesh::Vertices(a.V.rows() + b.V.rows(), 3),
               mesh::Faces(a.F.rows() + b.F.rows(), 3)};
    m.V << a.V, b.V;
    if (!interleave) {
        m.F << a.F, b.F;
        return m;
    }
    Eigen::Index fa = 0, fb = 0, f = 0;
    while (fa < a.F.rows() || fb < b.F.rows()) {
        if (fa < a.F.rows()) m.F.row(f++) = a.F.row(fa++);
        if (fb < b.F.rows()) m.F.row(f++) = b.F.row(fb++);
    }
    return m;
}

TEST(MeshComponents, TwoDisjointGridsGiveTwoComponentsWithTheirFaceCounts) {
    const TestMesh m = two_grids(3, 5, 0.0, true);
    const mesh::Components c = mesh::face_components(m.F, static_cast<int>(m.V.rows()));
    ASSERT_EQ(c.count(), 2);
    // Numbered by first face: face 0 is grid a's (2·3² = 18 faces), face 1 grid b's (50).
    EXPECT_EQ(c.faces[0], 18);
    EXPECT_EQ(c.faces[1], 50);
    // Each face's label is the grid it came from: a face of a uses only a's vertices.
    const int nva = 16;
    for (Eigen::Index f = 0; f < m.F.rows(); ++f) {
        EXPECT_EQ(c.face_component[static_cast<std::size_t>(f)], m.F(f, 0) < nva ? 0 : 1) << f;
    }
}

TEST(MeshComponents, FacesSharingOnlyAVertexAreConnected) {
    // Two triangles touching at vertex 2 only (a bow tie): one component.
    mesh::Faces F(2, 3);
    F << 0, 1, 2, 2, 3, 4;
    EXPECT_EQ(mesh::face_components(F, 5).count(), 1);
    // Unused vertices are no component.
    EXPECT_EQ(mesh::face_components(F, 9).count(), 1);
    EXPECT_EQ(mesh::face_components(mesh::Faces(0, 3), 4).count(), 0);
}

TEST(MeshComponents, ChainMergedInAnyOrderIsOneComponent) {
    // A strip of triangles listed from both ends towards the middle: the union-find must join
    // the two halves that grow separately until the last face.
    const int n = 9;
    mesh::Faces F(n, 3);
    std::vector<int> order;
    for (int i = 0; i < (n + 1) / 2; ++i) {
        order.push_back(i);
        if (n - 1 - i != i) order.push_back(n - 1 - i);
    }
    for (int k = 0; k < n; ++k) {
        const int i = order[static_cast<std::size_t>(k)];
        F.row(k) << i, i + 1, i + 2;
    }
    const mesh::Components c = mesh::face_components(F, n + 2);
    ASSERT_EQ(c.count(), 1);
    EXPECT_EQ(c.faces[0], n);
}

TEST(MeshComponents, IndexOutOfRangeIsDataError) {
    mesh::Faces F(1, 3);
    F << 0, 1, 3;
    EXPECT_THROW((void)mesh::face_components(F, 3), DataError);
}

TEST(MeshCompaction, KeepsFaceOrderAndGeometryAndDropsUnusedVertices) {
    const TestMesh m = plane_grid(4);
    std::vector<std::uint8_t> keep(static_cast<std::size_t>(m.F.rows()), 0);
    const std::vector<int> kept{3, 7, 8, 20, 31};
    for (const int f : kept) keep[static_cast<std::size_t>(f)] = 1;
    mesh::Vertices V = m.V;
    mesh::Faces F = m.F;
    mesh::compact_faces(V, F, keep);
    ASSERT_EQ(F.rows(), static_cast<Eigen::Index>(kept.size()));
    // Face k of the result is the k-th kept face, corner by corner at the same positions.
    for (std::size_t k = 0; k < kept.size(); ++k) {
        for (int c = 0; c < 3; ++c) {
            EXPECT_EQ(V.row(F(static_cast<Eigen::Index>(k), c)), m.V.row(m.F(kept[k], c)))
                << "face " << k << " corner " << c;
        }
    }
    // Only used vertices remain, each once, numbered by first use.
    std::set<int> used(F.data(), F.data() + F.size());
    EXPECT_EQ(static_cast<Eigen::Index>(used.size()), V.rows());
    int next = 0;
    std::vector<char> seen(static_cast<std::size_t>(V.rows()), 0);
    for (Eigen::Index f = 0; f < F.rows(); ++f) {
        for (int c = 0; c < 3; ++c) {
            if (seen[static_cast<std::size_t>(F(f, c))]) continue;
            EXPECT_EQ(F(f, c), next++);
            seen[static_cast<std::size_t>(F(f, c))] = 1;
        }
    }
}

TEST(MeshCompaction, KeepAllIsIdentityOnAMeshWithoutUnusedVertices) {
    const TestMesh m = plane_grid(3);
    mesh::Vertices V = m.V;
    mesh::Faces F = m.F;
    mesh::compact_faces(V, F, std::vector<std::uint8_t>(static_cast<std::size_t>(F.rows()), 1));
    // The grid's faces use the vertices in first-use order only if renumbering is a
    // permutation: compare geometry per face corner.
    ASSERT_EQ(F.rows(), m.F.rows());
    ASSERT_EQ(V.rows(), m.V.rows());
    for (Eigen::Index f = 0; f < F.rows(); ++f) {
        for (int c = 0; c < 3; ++c) EXPECT_EQ(V.row(F(f, c)), m.V.row(m.F(f, c)));
    }
}

TEST(MeshCompaction, WrongFlagCountIsUsageError) {
    TestMesh m = plane_grid(2);
    EXPECT_THROW(mesh::compact_faces(m.V, m.F, std::vector<std::uint8_t>(3, 1)), UsageError);
}

TEST(MeshLargestComponent, KeepsTheGridWithMoreFacesWhicheverComesFirst) {
    for (const bool big_first : {false, true}) {
        const TestMesh m = big_first ? two_grids(5, 3, 1.0, true) : two_grids(3, 5, 1.0, true);
        mesh::Vertices V = m.V;
        mesh::Faces F = m.F;
        EXPECT_EQ(mesh::keep_largest_component(V, F), 2);
        EXPECT_EQ(F.rows(), 50);
        EXPECT_EQ(V.rows(), 36);
        // The big grid is the one at x ≥ 10 (z = 1) when it came second, x ≤ 1 (z = 0) first.
        const double x = big_first ? 0.0 : 10.0;
        EXPECT_GE(V.col(0).minCoeff(), x);
        EXPECT_LE(V.col(0).maxCoeff(), x + 1.0);
        EXPECT_EQ(V.col(2).maxCoeff(), big_first ? 0.0 : 1.0);
    }
}

TEST(MeshLargestComponent, OneComponentIsLeftUntouched) {
    const TestMesh m = plane_grid(3);
    mesh::Vertices V = m.V;
    mesh::Faces F = m.F;
    EXPECT_EQ(mesh::keep_largest_component(V, F), 1);
    EXPECT_EQ(V, m.V);
    EXPECT_EQ(F, m.F);
}

TEST(MeshLargestComponent, TieKeepsTheComponentOfTheFirstFace) {
    const TestMesh m = two_grids(3, 3, 1.0, true);
    mesh::Vertices V = m.V;
    mesh::Faces F = m.F;
    EXPECT_EQ(mesh::keep_largest_component(V, F), 2);
    EXPECT_EQ(F.rows(), 18);
    EXPECT_EQ(V.col(2).maxCoeff(), 0.0);  // grid a (z = 0) holds face 0
}

TEST(MeshOrientation, FlipsADownwardGridAndLeavesAnUpwardOne) {
    const TestMesh up = plane_grid(4, 2.0);
    // Weighted normal of the +z grid: Σ 2·area = 2 · 4 (side 2).
    EXPECT_DOUBLE_EQ(mesh::weighted_normal_along(up.V, up.F, Eigen::Vector3d::UnitZ()), 8.0);
    mesh::Faces F = up.F;
    EXPECT_FALSE(mesh::orient_along(up.V, F, Eigen::Vector3d::UnitZ()));
    EXPECT_EQ(F, up.F);

    mesh::Faces down = up.F;
    down.col(1).swap(down.col(2));
    EXPECT_DOUBLE_EQ(mesh::weighted_normal_along(up.V, down, Eigen::Vector3d::UnitZ()), -8.0);
    EXPECT_TRUE(mesh::orient_along(up.V, down, Eigen::Vector3d::UnitZ()));
    EXPECT_EQ(down, up.F);
    const mesh::FaceGeometry g = mesh::face_geometry(up.V, down);
    for (Eigen::Index f = 0; f < down.rows(); ++f) EXPECT_EQ(g.normals(f, 2), 1.0);
}

TEST(MeshOrientation, TheAreaDecidesNotTheFaceCount) {
    // A large downward triangle and three small upward ones: the weighted normal is down.
    mesh::Vertices V(6, 3);
    V << 0, 0, 0, 10, 0, 0, 0, 10, 0, 20, 0, 0, 21, 0, 0, 20, 1, 0;
    mesh::Faces F(4, 3);
    F << 0, 2, 1,  // down, area 50
        3, 4, 5, 3, 4, 5, 3, 4, 5;  // up, 3 × 0.5
    EXPECT_TRUE(mesh::orient_along(V, F, Eigen::Vector3d::UnitZ()));
    EXPECT_EQ(F.row(0), Eigen::RowVector3i(0, 1, 2));
    EXPECT_EQ(F.row(1), Eigen::RowVector3i(3, 5, 4));
    // Along −z the original (now reversed) mesh is the right way up again.
    EXPECT_TRUE(mesh::orient_along(V, F, -Eigen::Vector3d::UnitZ()));
    EXPECT_EQ(F.row(0), Eigen::RowVector3i(0, 2, 1));
}

}  // namespace
}  // namespace octshape::test
