#pragma once
// Sections of a triangle mesh: where it crosses the zero level of a scalar field given at its
// vertices, e.g. a plane's signed distance. One straight segment per crossing face, its ends
// linearly interpolated along the face's two edges whose ends differ in sign (a triangle has
// either none or two). Used to draw a surface in the plane of a B-scan (the QC pictures).

#include <span>
#include <vector>

#include <Eigen/Core>

#include "octshape/mesh/mesh.h"

namespace octshape::mesh {

struct SectionSegment {
    Eigen::Vector3d a = Eigen::Vector3d::Zero();
    Eigen::Vector3d b = Eigen::Vector3d::Zero();
    int face = 0;
};

// Segments of the zero level of `values` (#V, one per vertex), in face order; each segment's
// ends in the order of the face's edges (edge 0 = a→b first). A value of exactly 0 counts as
// positive: a caller whose plane may pass through vertices (a grid's rows) moves it off them by
// a small offset. Throws UsageError when values.size() != #V.
[[nodiscard]] std::vector<SectionSegment> zero_level_segments(const Vertices& V,
                                                              const Faces& F,
                                                              std::span<const double> values);

// The section by the plane normal · p = offset (normal need not be unit length):
// zero_level_segments of normal · v - offset.
[[nodiscard]] std::vector<SectionSegment> plane_section(const Vertices& V,
                                                        const Faces& F,
                                                        const Eigen::Vector3d& normal,
                                                        double offset);

}  // namespace octshape::mesh
