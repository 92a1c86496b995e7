#pragma once
// What every denoiser of libmesh returns, and the noise estimate behind `--auto`.

#include <string>
#include <vector>

#include "octshape/mesh/mesh.h"

namespace octshape::mesh {

// Result of a denoiser (rofi.h, envt.h). The triangulation is the input's (never changed).
struct DenoiseResult {
    Vertices V;                         // #V×3 denoised positions
    int iterations = 0;                 // iterations run
    // RoFi with a stop or an observer (rofi.h, RofiProgress): δ and W of the returned mesh
    // before the fold repair; 0 when not measured.
    double displacement = 0;        // length unit
    double residual_whiteness = 0;
    double mean_centroid_distance = 0;  // c_a of the input (length unit)
    double radius = 0;                  // disk radius used for Ω_i (length unit)
    double mean_neighbourhood = 0;      // mean |Ω_i| (faces, incl. f_i)
    int fixed_vertices = 0;             // boundary vertices kept in place
    double seconds_setup = 0;           // adjacency + neighbourhoods
    double seconds_iterations = 0;      // all iterations and the fold repair
    // Fold-overs (folds.h) repaired: RoFi after its last iteration, ENVT every
    // EnvtParams::fold_repair_interval iterations and after the last (summed over the repairs).
    int folds_repaired = 0;
    int folds_left = 0;                 // fold-overs left after the last repair
    double seconds_fold_repair = 0;     // the repairs alone (part of seconds_iterations)
    // RoFi / bilateral: seconds_iterations split by phase (wall clock, summed over the
    // iterations; the rest of seconds_iterations is the fold repair and loop overhead): face
    // normals, areas and centroids; the pair weights f g; the sums of Eq. 5.1; the vertex
    // step; the stop's residual test (docs/algorithms/rofi.md, "Roofline"); and, once per
    // call before the iterations, the pair table of the shared weights.
    struct Phases {
        double pair_table = 0;
        double faces = 0;
        double weights = 0;
        double sums = 0;
        double vertices = 0;
        double stop = 0;
    } phases;
    std::vector<std::string> warnings;  // e.g. "mesh has non-manifold edges"
};

// Noise level of a mesh, estimated from the mesh alone (docs/algorithms/rofi.md).
//
// For each face, the normals of its edge-neighbours differ from its own by noise plus the
// true surface bending. On a smooth patch the bending between neighbours is small (≈ c_a κ),
// so the spread of normals on the quietest half of the surface measures the noise. Per face
// we take the median angle to its edge-neighbours; the estimate is the median of that over
// all faces (robust to sharp edges and corners, which are a minority of faces).
struct NoiseEstimate {
    double normal_angle_deg = 0;  // median over faces of the median neighbour-normal angle
    double noise_sigma = 0;       // σ_n / l_e from the vertex offsets (see below)
    double mean_edge_length = 0;  // l_e (length unit)
    double mean_centroid_distance = 0;  // c_a (length unit)
};

[[nodiscard]] NoiseEstimate estimate_noise(const Vertices& V, const Faces& F);

}  // namespace octshape::mesh
