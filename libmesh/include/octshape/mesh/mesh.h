#pragma once
// Triangle meshes: the arrays, the conventions, face geometry and adjacency.
//
// Conventions (written once, here; every file of libmesh follows them):
// - A mesh is a pair of plain arrays. V: #V×3 double, row i = (x, y, z) of vertex i, in the
//   caller's length unit (octshape works in mm). F: #F×3 int, row f = the three vertex indices
//   of triangle f, 0-based. Both are row-major so that a row is contiguous (VTK, OpenCV).
// - Orientation: a triangle (a, b, c) is counter-clockwise seen from the side its normal
//   points to; its normal is n = (b − a) × (c − a) / |(b − a) × (c − a)|. A closed mesh is
//   outward-oriented when the signed volume (metrics.h) is positive.
// - Edge numbering: edge k of face f joins F(f, k) and F(f, (k + 1) % 3) (edge 0 = a→b,
//   1 = b→c, 2 = c→a).
// - Connectivity never changes once built: the denoisers move vertices only. Adjacency is
//   built once by build_adjacency(); face geometry (normals, areas, centroids) is recomputed
//   by an explicit call to compute_face_geometry() whenever V changes — there is no cache
//   that could go stale.
// - Boundary: an edge used by exactly one face is a boundary edge; an edge used by three or
//   more faces is non-manifold. Vertices on either are "boundary vertices" (the denoisers keep
//   them fixed).
// - Errors: functions throw the project's error types (octshape/error.h): UsageError for a
//   parameter out of its range (naming the field), DataError for impossible data (naming the
//   face or vertex), AnalysisError when the data cannot support the method. libmesh knows
//   nothing of files: a caller that knows the file rethrows DataError as InputError naming it.

#include <cstddef>
#include <cstdint>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace octshape::mesh {

// #V×3 vertex positions (length unit of the caller, mm in octshape).
using Vertices = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>;
// #F×3 vertex indices per triangle, 0-based, counter-clockwise about the normal.
using Faces = Eigen::Matrix<int, Eigen::Dynamic, 3, Eigen::RowMajor>;

// Checks that F indexes only rows of V, that no triangle repeats a vertex, that V is finite and
// that some face has an area. Throws DataError naming the first bad face or vertex.
void validate_mesh(const Vertices& V, const Faces& F);

// Per-face geometry of the current vertex positions.
struct FaceGeometry {
    Vertices normals;       // #F×3 unit normals (zero row for a degenerate, zero-area face)
    Eigen::VectorXd areas;  // #F areas (length unit²)
    Vertices centroids;     // #F×3 barycentres (a + b + c) / 3, Eq. 2.31
};

// Fills `out` (resized as needed, so a reused FaceGeometry allocates only once).
void compute_face_geometry(const Vertices& V, const Faces& F, FaceGeometry& out);
[[nodiscard]] FaceGeometry face_geometry(const Vertices& V, const Faces& F);

// Compressed sparse rows: the items of row i are items[offsets[i] .. offsets[i+1]).
struct Csr {
    std::vector<int> offsets;  // #rows+1, cumulative counts with a leading zero
    std::vector<int> items;    // offsets.back() entries

    [[nodiscard]] int rows() const { return static_cast<int>(offsets.size()) - 1; }
    [[nodiscard]] int begin(int i) const { return offsets[static_cast<std::size_t>(i)]; }
    [[nodiscard]] int end(int i) const { return offsets[static_cast<std::size_t>(i) + 1]; }
    [[nodiscard]] int size(int i) const { return end(i) - begin(i); }
    [[nodiscard]] int item(int k) const { return items[static_cast<std::size_t>(k)]; }

    // Packs per-row lists (row i = rows[i], order kept).
    [[nodiscard]] static Csr from_rows(const std::vector<std::vector<int>>& rows);
};

// Adjacency of a fixed triangulation; built once.
struct Adjacency {
    Csr vertex_faces;     // #V rows: faces containing the vertex, ascending face index
    Csr vertex_vertices;  // #V rows: vertices sharing an edge with it (1-ring), ascending
    Csr face_faces;       // #F rows: faces sharing an edge with the face, ascending
    std::vector<std::uint8_t> boundary_vertex;  // #V, 1 = on a boundary or non-manifold edge
    int boundary_edges = 0;     // edges used by exactly one face
    int nonmanifold_edges = 0;  // edges used by three or more faces
};

// Builds every adjacency of F over `num_vertices` vertices (F must index below it).
[[nodiscard]] Adjacency build_adjacency(const Faces& F, int num_vertices);

// c_a: mean distance between the centroids of edge-adjacent faces (each adjacent pair counted
// once). RoFi uses r = 2 c_a and σ_c = c_a (§5.2). Returns 0 for a mesh without such pairs.
[[nodiscard]] double mean_centroid_distance(const FaceGeometry& geometry,
                                            const Adjacency& adjacency);

// Mean edge length l_e (each edge counted once): the unit of the noise levels in §3.1.5.
[[nodiscard]] double mean_edge_length(const Vertices& V, const Faces& F);

// The most faces a disk neighbourhood may hold on a mesh of `faces` faces: a quarter of the
// mesh, at least 64 and at most 4096.
[[nodiscard]] std::size_t max_neighbourhood_faces(int faces);

// Geometric (disk) neighbourhoods Ω_i = {f_j : |c_j − c_i| ≤ r} (§3.1.1), grown from f_i
// through faces sharing a vertex and stopped where the centroid leaves the disk, so that a
// disk never jumps across a gap to another sheet of the surface. Row i lists f_i itself first,
// then the other faces in ascending index order (a fixed order keeps sums reproducible).
// Uses `threads` std::threads (≥ 1); the result does not depend on it.
// Bounded: a disk holding more than max_neighbourhood_faces(#F) faces throws
// DataError naming the radius and the face (docs/algorithms/mesh.md,
// "Neighbourhood bound"), before the growth costs more than that bound per face.
[[nodiscard]] Csr disk_neighbourhoods(const Faces& F,
                                      const FaceGeometry& geometry,
                                      const Adjacency& adjacency,
                                      double radius,
                                      int threads = 1);

}  // namespace octshape::mesh
