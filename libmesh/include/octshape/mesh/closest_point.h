#pragma once
// Closest points on a triangle surface, through a bounding-volume hierarchy (AABB tree).
// Used by E_v (metrics.h) and by anything that needs the distance to a surface rather than
// to its vertices.

#include <vector>

#include <Eigen/Core>

#include "octshape/mesh/mesh.h"

namespace octshape::mesh {

// The point of triangle (a, b, c) closest to p (exact; degenerate triangles are handled as
// their edges or points). Ericson, Real-Time Collision Detection, §5.1.5.
[[nodiscard]] Eigen::Vector3d closest_point_on_triangle(const Eigen::Vector3d& p,
                                                        const Eigen::Vector3d& a,
                                                        const Eigen::Vector3d& b,
                                                        const Eigen::Vector3d& c);

struct SurfaceHit {
    Eigen::Vector3d point = Eigen::Vector3d::Zero();  // closest point on the surface
    double distance = 0.0;                            // |p − point|, length unit of V
    int face = -1;                                    // triangle that holds `point`
};

// An AABB tree over the triangles of (V, F), built once (O(#F log #F)); queries are
// O(log #F) on typical meshes. Keeps its own copy of the mesh. Thread-safe for queries.
class TriangleTree {
public:
    // Throws DataError if the mesh is invalid (validate_mesh) or has no face.
    TriangleTree(const Vertices& V, const Faces& F);

    // The closest point of the whole surface to p.
    [[nodiscard]] SurfaceHit closest(const Eigen::Vector3d& p) const;

private:
    struct Node {
        Eigen::Vector3d lo;
        Eigen::Vector3d hi;
        int first = 0;   // leaf: first index into order_; inner: left child (right = left+1)
        int count = 0;   // leaf: number of triangles; inner: 0
    };
    void build(int index, int first, int count, std::vector<Eigen::Vector3d>& centres);

    Vertices V_;
    Faces F_;
    std::vector<int> order_;  // triangle indices, grouped by leaf
    std::vector<Node> nodes_;
};

}  // namespace octshape::mesh
