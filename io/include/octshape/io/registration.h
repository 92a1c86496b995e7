#pragma once
// Rigid registration of triangle surfaces by VTK's iterative closest point
// (vtkIterativeClosestPointTransform, rigid-body mode): thesis §8.2.1. The source's vertices
// are the landmarks; their partners are the closest points ON the target surface (VTK's cell
// locator). The transform maps source coordinates to target coordinates: x' = R x + t.

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "octshape/mesh/mesh.h"

namespace octshape::io {

struct IcpParams {
    int max_iterations = 500;       // ICP iterations at most; ≥ 1
    // Stop when the RMS movement of the landmarks between two iterations falls below
    // tolerance × the target's bounding-box diagonal (dimensionless); > 0.
    double tolerance = 1e-9;
    // Landmarks: VTK uses every ⌈#V / max_landmarks⌉-th source vertex; 0 = every vertex.
    int max_landmarks = 5000;
    bool match_centroids = true;    // start by moving the source centroid onto the target's

    // Throws std::invalid_argument naming the first bad field.
    void validate() const;
};

struct IcpResult {
    Eigen::Isometry3d transform = Eigen::Isometry3d::Identity();  // source → target
    int iterations = 0;          // ICP iterations run (VTK's count)
    double rotation_deg = 0;     // rotation angle of `transform`
    double translation = 0;      // |t| (length unit)
    // Distances of the transformed source vertices to the target surface (libmesh AABB):
    double mean_distance = 0;    // mean (length unit)
    double rms_distance = 0;     // root mean square (length unit)
    double max_distance = 0;     // maximum (length unit)
};

// Registers `source` to `target`. Throws std::invalid_argument for invalid meshes (validate_mesh)
// or parameters.
[[nodiscard]] IcpResult icp_rigid(const mesh::Vertices& source_V,
                                  const mesh::Vertices& target_V,
                                  const mesh::Faces& target_F,
                                  const IcpParams& params = {});

// Applies x' = T x to every row.
[[nodiscard]] mesh::Vertices transformed(const mesh::Vertices& V, const Eigen::Isometry3d& T);

}  // namespace octshape::io
