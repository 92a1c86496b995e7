#pragma once
// Rigid registration of triangle surfaces (thesis §8.2.1) in two stages:
//  1. VTK's iterative closest point (vtkIterativeClosestPointTransform, rigid-body mode): the
//     source's vertices are the landmarks, their partners the closest points ON the target
//     surface (VTK's cell locator). Point-to-point ICP has a wide basin of convergence but
//     converges only linearly on smooth surfaces (hundreds of iterations, see
//     docs/algorithms/meanshape.md).
//  2. Point-to-plane refinement (Chen & Medioni 1992): Gauss–Newton on
//     Σ ((R x_i + t − q_i) · n_i)² with q_i the closest point on the target and n_i the normal
//     of its triangle, pairs farther than 3 × the median distance left out (they hang over the
//     target's boundary). Converges quadratically from stage 1's answer.
// The transform maps source coordinates to target coordinates: x' = R x + t.

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "octshape/mesh/mesh.h"

namespace octshape::io {

struct IcpParams {
    int max_iterations = 100;       // VTK ICP iterations at most; ≥ 1
    // Stop when the RMS movement of the landmarks between two iterations falls below
    // tolerance × the target's bounding-box diagonal (dimensionless); > 0.
    double tolerance = 1e-9;
    // Landmarks: VTK uses every ⌈#V / max_landmarks⌉-th source vertex; 0 = every vertex.
    int max_landmarks = 5000;
    bool match_centroids = true;    // start by moving the source centroid onto the target's
    // Point-to-plane Gauss–Newton steps after VTK's ICP, at most; 0 = VTK's ICP only. Stops
    // early when a step moves every source vertex by less than 1e-12 × the target's diagonal.
    int refine_iterations = 50;

    // Throws UsageError naming the first bad field.
    void validate() const;
};

struct IcpResult {
    Eigen::Isometry3d transform = Eigen::Isometry3d::Identity();  // source → target
    int iterations = 0;          // ICP iterations run (VTK's count)
    int refine_iterations = 0;   // point-to-plane steps run after it
    double rotation_deg = 0;     // rotation angle of `transform`
    double translation = 0;      // |t| (length unit)
    // Distances of the transformed source vertices to the target surface (libmesh AABB):
    double mean_distance = 0;    // mean (length unit)
    double rms_distance = 0;     // root mean square (length unit)
    double max_distance = 0;     // maximum (length unit)
};

// Registers `source` to `target`. Throws DataError for invalid meshes (validate_mesh),
// UsageError for bad parameters.
[[nodiscard]] IcpResult icp_rigid(const mesh::Vertices& source_V,
                                  const mesh::Vertices& target_V,
                                  const mesh::Faces& target_F,
                                  const IcpParams& params = {});

// Applies x' = T x to every row.
[[nodiscard]] mesh::Vertices transformed(const mesh::Vertices& V, const Eigen::Isometry3d& T);

}  // namespace octshape::io
