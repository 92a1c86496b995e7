#pragma once
// Quality and error measures of a (denoised) mesh against a reference (§3.2.3, §5.2.2).

#include "octshape/mesh/closest_point.h"
#include "octshape/mesh/mesh.h"

namespace octshape::mesh {

// E_v (§3.2.3): sqrt( Σ_i Σ_{j∈F_v(i)} A_j dist(v_i, T)² / (3 Σ_k A_k) ), the area-weighted
// RMS of the distance from each vertex of (V, F) to the closest point of the reference
// triangles (through `reference`'s AABB tree, not only its vertices). A_j are areas of (V, F).
// Length unit of V. 0 for a mesh of zero area.
[[nodiscard]] double vertex_error(const Vertices& V, const Faces& F, const TriangleTree& reference);

// MSAE (§3.2.3): mean angle in degrees between the normals of corresponding faces (face f of
// F against face f of reference_F; the two meshes must share the triangulation, i.e. F ==
// reference_F). Throws DataError otherwise.
[[nodiscard]] double mean_angle_error_deg(const Vertices& V,
                                          const Faces& F,
                                          const Vertices& reference_V,
                                          const Faces& reference_F);

// Mesh quality Q (§5.2.2): mean over faces of circumradius / shortest edge. 1/√3 ≈ 0.577 for
// equilateral triangles, larger for worse ones, +∞ if any face is degenerate.
[[nodiscard]] double mesh_quality(const Vertices& V, const Faces& F);

// Faces whose normal is more than 90° from the normal of the corresponding reference face
// (same triangulation required, as for the MSAE).
[[nodiscard]] int flipped_faces(const Vertices& V,
                                const Faces& F,
                                const Vertices& reference_V,
                                const Faces& reference_F);

// A denoiser's flips against its input (meshes/README: "zero flipped faces" means none that
// the denoiser creates): faces flipped (normal > 90° from the reference's, as above) in the
// input, in the output, created (flipped in the output, not in the input), kept (in both) and
// fixed (in the input, not in the output). All three meshes share the triangulation F.
struct FlipTransitions {
    int input = 0;    // flipped in the input
    int output = 0;   // flipped in the output = created + kept
    int created = 0;  // flipped in the output only
    int kept = 0;     // flipped in both
    int fixed = 0;    // flipped in the input only; input = kept + fixed
};

// Throws DataError if the triangulations differ or a mesh is invalid.
[[nodiscard]] FlipTransitions flip_transitions(const Vertices& output_V,
                                               const Vertices& input_V,
                                               const Vertices& reference_V,
                                               const Faces& F);

// Signed enclosed volume Σ_f a·(b × c) / 6 (divergence theorem; length unit³). Positive for a
// closed, outward-oriented mesh; for an open mesh it depends on the origin.
[[nodiscard]] double signed_volume(const Vertices& V, const Faces& F);

// Everything above for a mesh against its reference (same triangulation).
struct MeshComparison {
    double vertex_error = 0.0;        // E_v, length unit
    double msae_deg = 0.0;            // MSAE, degrees
    double quality = 0.0;             // Q of the mesh
    double reference_quality = 0.0;   // Q of the reference
    int flipped_faces = 0;            // normals > 90° from the reference's
    double volume = 0.0;              // signed volume of the mesh, length unit³
    double reference_volume = 0.0;    // signed volume of the reference
    double volume_change = 0.0;       // (volume − reference_volume) / |reference_volume|
    bool closed = false;              // the mesh has no boundary or non-manifold edge
};

// Throws DataError if either mesh is invalid or the triangulations differ.
[[nodiscard]] MeshComparison compare_meshes(const Vertices& V,
                                            const Faces& F,
                                            const Vertices& reference_V,
                                            const Faces& reference_F);

}  // namespace octshape::mesh
