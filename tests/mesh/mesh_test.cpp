// libmesh core: face geometry, adjacency, boundary, c_a, disk neighbourhoods.

#include "octshape/error.h"
#include "octshape/mesh/mesh.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <numbers>
#include <set>
#include <stdexcept>
#include <vector>

#include "mesh/mesh_fixtures.h"

namespace octshape::test {
namespace {

using mesh::Adjacency;
using mesh::build_adjacency;
using mesh::face_geometry;

TEST(MeshGeometry, CounterClockwiseTriangleHasPlusZNormalAreaAndCentroid) {
    mesh::Vertices V(3, 3);
    V << 0, 0, 0, 2, 0, 0, 0, 3, 0;
    mesh::Faces F(1, 3);
    F << 0, 1, 2;
    const auto g = face_geometry(V, F);
    EXPECT_EQ(g.normals.row(0), Eigen::RowVector3d(0, 0, 1));
    EXPECT_DOUBLE_EQ(g.areas(0), 3.0);
    EXPECT_TRUE(g.centroids.row(0).isApprox(Eigen::RowVector3d(2.0 / 3.0, 1.0, 0.0)));
}

TEST(MeshGeometry, UnitNormalsAndTotalAreaOverTheFamily) {
    for (const auto& m : noisy_family()) {
        const auto g = face_geometry(m.V, m.F);
        for (Eigen::Index f = 0; f < m.F.rows(); ++f) {
            EXPECT_NEAR(g.normals.row(f).norm(), 1.0, 1e-14) << m.name << " face " << f;
        }
    }
    // Known areas: the grid covers exactly the unit square, the cube 6 × 4.
    EXPECT_NEAR(face_geometry(plane_grid(5).V, plane_grid(5).F).areas.sum(), 1.0, 1e-14);
    EXPECT_NEAR(face_geometry(cube(3).V, cube(3).F).areas.sum(), 24.0, 1e-12);
}

TEST(MeshAdjacency, ClosedMeshesHaveNoBoundaryAndEulerCharacteristicTwo) {
    for (const auto& m : {icosphere(2), cube(4)}) {
        const Adjacency a = build_adjacency(m.F, static_cast<int>(m.V.rows()));
        EXPECT_EQ(a.boundary_edges, 0) << m.name;
        EXPECT_EQ(a.nonmanifold_edges, 0) << m.name;
        for (const auto b : a.boundary_vertex) EXPECT_EQ(b, 0);
        const long edges = static_cast<long>(a.vertex_vertices.items.size()) / 2;
        EXPECT_EQ(m.V.rows() - edges + m.F.rows(), 2) << m.name;
        for (int f = 0; f < a.face_faces.rows(); ++f) EXPECT_EQ(a.face_faces.size(f), 3);
        EXPECT_EQ(static_cast<long>(a.vertex_faces.items.size()), 3 * m.F.rows());
    }
}

TEST(MeshAdjacency, GridBoundaryIsItsOuterRing) {
    const int n = 7;
    const auto m = plane_grid(n);
    const Adjacency a = build_adjacency(m.F, static_cast<int>(m.V.rows()));
    EXPECT_EQ(a.boundary_edges, 4 * n);
    for (int j = 0; j <= n; ++j) {
        for (int i = 0; i <= n; ++i) {
            const bool outer = i == 0 || j == 0 || i == n || j == n;
            EXPECT_EQ(a.boundary_vertex[static_cast<std::size_t>(j * (n + 1) + i)], outer ? 1 : 0);
        }
    }
    // Vertex → faces lists each face of the vertex once, ascending.
    for (int v = 0; v < a.vertex_faces.rows(); ++v) {
        for (int p = a.vertex_faces.begin(v); p + 1 < a.vertex_faces.end(v); ++p) {
            EXPECT_LT(a.vertex_faces.item(p), a.vertex_faces.item(p + 1));
        }
        for (int p = a.vertex_faces.begin(v); p < a.vertex_faces.end(v); ++p) {
            const int f = a.vertex_faces.item(p);
            EXPECT_TRUE(m.F(f, 0) == v || m.F(f, 1) == v || m.F(f, 2) == v);
        }
    }
}

TEST(MeshAdjacency, NonManifoldEdgeIsCountedAndItsVerticesAreBoundary) {
    mesh::Vertices V(5, 3);
    V << 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, -1, 0, 0, 0, 1;
    mesh::Faces F(3, 3);
    F << 0, 1, 2, 1, 0, 3, 0, 1, 4;  // edge 0–1 has three faces
    const Adjacency a = build_adjacency(F, 5);
    EXPECT_EQ(a.nonmanifold_edges, 1);
    EXPECT_EQ(a.boundary_vertex[0], 1);
    EXPECT_EQ(a.boundary_vertex[1], 1);
}

// Every CSR of build_adjacency equals its definition evaluated by brute force over all pairs
// (rows ascending, no repeats), on the family and on a mesh with a non-manifold edge and a
// face pair sharing two edges' worth of vertices through different faces.
TEST(MeshAdjacency, EveryListEqualsItsBruteForceDefinition) {
    auto meshes = noisy_family();
    TestMesh fan;
    fan.name = "non-manifold fan";
    fan.V.resize(6, 3);
    fan.V << 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, -1, 0, 0, 0, 1, 1, 1, 1;
    fan.F.resize(4, 3);
    fan.F << 0, 1, 2, 1, 0, 3, 0, 1, 4, 1, 5, 2;
    meshes.push_back(fan);
    const auto rows_of = [](const mesh::Csr& c) {
        std::vector<std::vector<int>> out(static_cast<std::size_t>(c.rows()));
        for (int i = 0; i < c.rows(); ++i) {
            for (int p = c.begin(i); p < c.end(i); ++p) {
                out[static_cast<std::size_t>(i)].push_back(c.item(p));
            }
        }
        return out;
    };
    for (const auto& m : meshes) {
        const int nv = static_cast<int>(m.V.rows());
        const int nf = static_cast<int>(m.F.rows());
        const Adjacency a = build_adjacency(m.F, nv);
        const auto has = [&](int f, int v) {
            return m.F(f, 0) == v || m.F(f, 1) == v || m.F(f, 2) == v;
        };
        // u and v are 1-ring neighbours iff some face contains both.
        std::vector<std::uint8_t> joined(static_cast<std::size_t>(nv) * nv, 0);
        for (int f = 0; f < nf; ++f) {
            for (int k = 0; k < 3; ++k) {
                for (int l = 0; l < 3; ++l) {
                    if (k != l) joined[static_cast<std::size_t>(m.F(f, k)) * nv + m.F(f, l)] = 1;
                }
            }
        }
        std::vector<std::vector<int>> vf(static_cast<std::size_t>(nv));
        std::vector<std::vector<int>> vv(static_cast<std::size_t>(nv));
        std::vector<std::vector<int>> ff(static_cast<std::size_t>(nf));
        for (int v = 0; v < nv; ++v) {
            for (int f = 0; f < nf; ++f) {
                if (has(f, v)) vf[static_cast<std::size_t>(v)].push_back(f);
            }
            for (int u = 0; u < nv; ++u) {
                if (joined[static_cast<std::size_t>(v) * nv + u] != 0) {
                    vv[static_cast<std::size_t>(v)].push_back(u);
                }
            }
        }
        for (int f = 0; f < nf; ++f) {
            for (int g = 0; g < nf; ++g) {
                if (g == f) continue;
                int shared = 0;
                for (int k = 0; k < 3; ++k) shared += has(g, m.F(f, k)) ? 1 : 0;
                if (shared >= 2) ff[static_cast<std::size_t>(f)].push_back(g);
            }
        }
        EXPECT_EQ(rows_of(a.vertex_faces), vf) << m.name;
        EXPECT_EQ(rows_of(a.vertex_vertices), vv) << m.name;
        EXPECT_EQ(rows_of(a.face_faces), ff) << m.name;
    }
}

TEST(MeshCentroidDistance, RegularGridMatchesClosedForm) {
    // Grid of n×n squares of side h: n² diagonal pairs at h√2/3 and 2n(n−1) pairs across
    // the square sides at h√5/3 (centroids (2h/3, h/3) and (4h/3, 2h/3), and the transpose).
    const int n = 6;
    const double h = 1.0 / n;
    const auto m = plane_grid(n);
    const auto g = face_geometry(m.V, m.F);
    const Adjacency a = build_adjacency(m.F, static_cast<int>(m.V.rows()));
    const double diag = n * n;
    const double side = 2.0 * n * (n - 1);
    const double expected =
        h * (diag * std::sqrt(2.0) + side * std::sqrt(5.0)) / (3.0 * (diag + side));
    EXPECT_NEAR(mesh::mean_centroid_distance(g, a), expected, 1e-14);
    EXPECT_NEAR(mesh::mean_edge_length(m.V, m.F),
                h * (2.0 * n * (n + 1) + n * n * std::sqrt(2.0)) / (2.0 * n * (n + 1) + n * n),
                1e-14);
}

TEST(MeshNeighbourhoods, DiskEqualsBruteForceOnAConvexPatchAndListsTheFaceFirst) {
    const auto m = with_noise(plane_grid(12), 0.005);
    const auto g = face_geometry(m.V, m.F);
    const Adjacency a = build_adjacency(m.F, static_cast<int>(m.V.rows()));
    const double r = 2.5 * mesh::mean_centroid_distance(g, a);
    const mesh::Csr disk = mesh::disk_neighbourhoods(m.F, g, a, r);
    ASSERT_EQ(disk.rows(), m.F.rows());
    for (int i = 0; i < disk.rows(); ++i) {
        std::set<int> brute;
        for (int j = 0; j < m.F.rows(); ++j) {
            if ((g.centroids.row(i) - g.centroids.row(j)).norm() <= r) brute.insert(j);
        }
        std::set<int> grown;
        for (int p = disk.begin(i); p < disk.end(i); ++p) grown.insert(disk.item(p));
        EXPECT_EQ(grown, brute) << "face " << i;
        EXPECT_EQ(disk.item(disk.begin(i)), i);
        for (int p = disk.begin(i) + 1; p + 1 < disk.end(i); ++p) {
            EXPECT_LT(disk.item(p), disk.item(p + 1));
        }
    }
}

TEST(MeshNeighbourhoods, DiskDoesNotJumpAcrossAGapToAnotherSheet) {
    // Two parallel sheets 0.01 apart: Euclidean neighbours, but not connected.
    auto a = plane_grid(4);
    auto b = plane_grid(4);
    mesh::Vertices V(a.V.rows() * 2, 3);
    V << a.V, b.V.rowwise() + Eigen::RowVector3d(0, 0, 0.01);
    mesh::Faces F(a.F.rows() * 2, 3);
    F << a.F, (b.F.array() + static_cast<int>(a.V.rows())).matrix();
    const auto g = face_geometry(V, F);
    const Adjacency adj = build_adjacency(F, static_cast<int>(V.rows()));
    const mesh::Csr disk = mesh::disk_neighbourhoods(F, g, adj, 0.3);
    for (int p = disk.begin(0); p < disk.end(0); ++p) EXPECT_LT(disk.item(p), a.F.rows());
}

TEST(MeshNeighbourhoods, SameForAnyThreadCount) {
    const auto m = with_noise(icosphere(3), 0.02);
    const auto g = face_geometry(m.V, m.F);
    const Adjacency a = build_adjacency(m.F, static_cast<int>(m.V.rows()));
    const double r = 2.0 * mesh::mean_centroid_distance(g, a);
    const auto one = mesh::disk_neighbourhoods(m.F, g, a, r, 1);
    const auto three = mesh::disk_neighbourhoods(m.F, g, a, r, 3);
    EXPECT_EQ(one.offsets, three.offsets);
    EXPECT_EQ(one.items, three.items);
}

TEST(MeshNeighbourhoods, ADiskPastTheBoundIsRefusedNamingRadiusAndFace) {
    // icosphere(3): 1280 faces, bound 320. One vertex moved 1e6 away inflates c_a from ~0.1 to
    // ~1000 (the six pairs between its faces and the others, ~3e5 apart, dominate the mean of
    // ~1920 pairs), so a disk of 2 c_a holds every face: refused at the first face.
    EXPECT_EQ(mesh::max_neighbourhood_faces(1280), 320U);
    EXPECT_EQ(mesh::max_neighbourhood_faces(10), 64U);
    EXPECT_EQ(mesh::max_neighbourhood_faces(1000000), 4096U);
    auto m = icosphere(3);
    const auto g0 = face_geometry(m.V, m.F);
    const Adjacency a = build_adjacency(m.F, static_cast<int>(m.V.rows()));
    // The default disk on the clean sphere is far inside the bound.
    const mesh::Csr fine =
        mesh::disk_neighbourhoods(m.F, g0, a, 2.0 * mesh::mean_centroid_distance(g0, a));
    for (int i = 0; i < fine.rows(); ++i) EXPECT_LT(fine.end(i) - fine.begin(i), 64);
    m.V(0, 0) = 1e6;
    const auto g = face_geometry(m.V, m.F);
    const double r = 2.0 * mesh::mean_centroid_distance(g, a);
    EXPECT_GT(r, 4.0);  // wider than the unit sphere's diameter
    try {
        (void)mesh::disk_neighbourhoods(m.F, g, a, r, 2);
        FAIL() << "a disk holding every face was accepted";
    } catch (const DataError& e) {
        const std::string what = e.what();
        EXPECT_NE(what.find("more than 320 of the 1280 faces"), std::string::npos) << what;
        EXPECT_NE(what.find("around face "), std::string::npos) << what;
    }
}

TEST(MeshValidate, NamesTheBadFaceOrVertex) {
    mesh::Vertices V(3, 3);
    V << 0, 0, 0, 1, 0, 0, 0, 1, 0;
    mesh::Faces F(1, 3);
    F << 0, 1, 3;
    EXPECT_THROW(mesh::validate_mesh(V, F), octshape::DataError);
    F << 0, 1, 1;
    EXPECT_THROW(mesh::validate_mesh(V, F), octshape::DataError);
    F << 0, 1, 2;
    EXPECT_NO_THROW(mesh::validate_mesh(V, F));
    V(1, 2) = std::nan("");
    try {
        mesh::validate_mesh(V, F);
        FAIL() << "NaN vertex accepted";
    } catch (const octshape::DataError& e) {
        EXPECT_NE(std::string(e.what()).find("vertex 1"), std::string::npos) << e.what();
    }
    EXPECT_THROW((void)mesh::disk_neighbourhoods(F, face_geometry(V, F), Adjacency{}, -1.0),
                 octshape::UsageError);
}

TEST(MeshValidate, ASurfaceNeedsAFaceWithArea) {
    // Two faces: one on a line (no area) is tolerated while the other has area; both on the
    // same line is no surface at all.
    mesh::Vertices V(4, 3);
    V << 0, 0, 0, 1, 0, 0, 2, 0, 0, 0, 1, 0;
    mesh::Faces F(2, 3);
    F << 0, 1, 2, 0, 1, 3;
    EXPECT_NO_THROW(mesh::validate_mesh(V, F));
    V.row(3) << 3, 0, 0;
    try {
        mesh::validate_mesh(V, F);
        FAIL() << "a mesh of collinear vertices accepted";
    } catch (const octshape::DataError& e) {
        EXPECT_NE(std::string(e.what()).find("zero area"), std::string::npos) << e.what();
    }
}

}  // namespace
}  // namespace octshape::test
