#pragma once
// Connectivity edits of a triangle mesh: connected components, compaction (keep a subset of the
// faces), the largest component, orientation by the area-weighted normal
// (docs/algorithms/mesh.md, "Components, compaction, orientation"). Conventions: mesh.h.
//
// These are the only libmesh functions that change connectivity; they return new arrays (or
// edit V and F in place) and never move a vertex.

#include <cstdint>
#include <vector>

#include "octshape/mesh/mesh.h"

namespace octshape::mesh {

// Connected components of the faces: two faces are connected when they share a vertex
// (union-find over the vertices). Components are numbered 0, 1, … in the order of their first
// face, so the numbering depends only on F, not on how the union-find merged.
struct Components {
    std::vector<int> face_component;  // #F, the component of each face
    std::vector<std::int64_t> faces;  // faces per component (size = number of components)

    [[nodiscard]] int count() const { return static_cast<int>(faces.size()); }
};

// Throws DataError if F indexes outside [0, num_vertices).
[[nodiscard]] Components face_components(const Faces& F, int num_vertices);

// Keeps the faces f with keep[f] != 0, in their order, and the vertices they use: the kept
// vertices are renumbered 0, 1, … in the order of their first use by the kept faces (the face
// order, then corners 0, 1, 2), their positions copied unchanged. keep.size() must be #F
// (UsageError otherwise).
void compact_faces(Vertices& V, Faces& F, const std::vector<std::uint8_t>& keep);

// Keeps the largest connected component (most faces; ties: the one with the lowest-numbered
// first face) by compact_faces; leaves V and F untouched when there is at most one component.
// Returns the number of components of the input.
int keep_largest_component(Vertices& V, Faces& F);

// Σ_f (b − a) × (c − a) · direction: twice the area-weighted mean normal's component along
// `direction`, summed over the faces in index order.
[[nodiscard]] double weighted_normal_along(const Vertices& V, const Faces& F,
                                           const Eigen::Vector3d& direction);

// Orients the mesh so that its area-weighted normal has a non-negative component along
// `direction` (every face reversed, corners 1 and 2 swapped, when it is negative). Returns
// true when the faces were reversed. One orientation for the whole mesh: a mesh whose faces
// are not consistently oriented stays inconsistent.
bool orient_along(const Vertices& V, Faces& F, const Eigen::Vector3d& direction);

}  // namespace octshape::mesh
