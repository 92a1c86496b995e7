#include "octshape/mesh/metrics.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <stdexcept>
#include <string>

#include "octshape/error.h"

namespace octshape::mesh {
namespace {

void require_same_triangulation(const Vertices& V,
                                const Faces& F,
                                const Vertices& reference_V,
                                const Faces& reference_F) {
    if (F.rows() != reference_F.rows() || V.rows() != reference_V.rows() || F != reference_F) {
        throw DataError(
            "reference_F: the mesh and the reference must share the triangulation (" +
            std::to_string(V.rows()) + "/" + std::to_string(F.rows()) + " vs " +
            std::to_string(reference_V.rows()) + "/" + std::to_string(reference_F.rows()) +
            " vertices/faces, or different faces)");
    }
}

}  // namespace

double vertex_error(const Vertices& V, const Faces& F, const TriangleTree& reference) {
    const FaceGeometry g = face_geometry(V, F);
    Eigen::VectorXd vertex_area = Eigen::VectorXd::Zero(V.rows());  // Σ_{j∈F_v(i)} A_j
    for (Eigen::Index f = 0; f < F.rows(); ++f) {
        for (int k = 0; k < 3; ++k) vertex_area(F(f, k)) += g.areas(f);
    }
    const double total = 3.0 * g.areas.sum();
    if (!(total > 0.0)) return 0.0;
    double sum = 0.0;
    for (Eigen::Index i = 0; i < V.rows(); ++i) {
        if (vertex_area(i) == 0.0) continue;
        const double d = reference.closest(V.row(i).transpose()).distance;
        sum += vertex_area(i) * d * d;
    }
    return std::sqrt(sum / total);
}

double mean_angle_error_deg(const Vertices& V,
                            const Faces& F,
                            const Vertices& reference_V,
                            const Faces& reference_F) {
    require_same_triangulation(V, F, reference_V, reference_F);
    if (F.rows() == 0) return 0.0;
    const FaceGeometry g = face_geometry(V, F);
    const FaceGeometry r = face_geometry(reference_V, reference_F);
    double sum = 0.0;
    for (Eigen::Index f = 0; f < F.rows(); ++f) {
        // atan2 of |n × m| and n·m is accurate near 0° and 180°, unlike acos.
        const Eigen::Vector3d n = g.normals.row(f);
        const Eigen::Vector3d m = r.normals.row(f);
        sum += std::atan2(n.cross(m).norm(), n.dot(m));
    }
    return sum / static_cast<double>(F.rows()) * 180.0 / std::numbers::pi;
}

double mesh_quality(const Vertices& V, const Faces& F) {
    if (F.rows() == 0) return 0.0;
    double sum = 0.0;
    for (Eigen::Index f = 0; f < F.rows(); ++f) {
        const Eigen::Vector3d a = V.row(F(f, 0));
        const Eigen::Vector3d b = V.row(F(f, 1));
        const Eigen::Vector3d c = V.row(F(f, 2));
        const double la = (b - c).norm();
        const double lb = (c - a).norm();
        const double lc = (a - b).norm();
        const double twice_area = (b - a).cross(c - a).norm();
        const double shortest = std::min({la, lb, lc});
        if (!(twice_area > 0.0) || !(shortest > 0.0)) {
            return std::numeric_limits<double>::infinity();
        }
        const double circumradius = la * lb * lc / (2.0 * twice_area);  // abc / (4 A)
        sum += circumradius / shortest;
    }
    return sum / static_cast<double>(F.rows());
}

int flipped_faces(const Vertices& V,
                  const Faces& F,
                  const Vertices& reference_V,
                  const Faces& reference_F) {
    require_same_triangulation(V, F, reference_V, reference_F);
    const FaceGeometry g = face_geometry(V, F);
    const FaceGeometry r = face_geometry(reference_V, reference_F);
    int flips = 0;
    for (Eigen::Index f = 0; f < F.rows(); ++f) {
        if (g.normals.row(f).dot(r.normals.row(f)) < 0.0) ++flips;
    }
    return flips;
}

FlipTransitions flip_transitions(const Vertices& output_V,
                                 const Vertices& input_V,
                                 const Vertices& reference_V,
                                 const Faces& F) {
    require_same_triangulation(output_V, F, reference_V, F);
    require_same_triangulation(input_V, F, reference_V, F);
    const FaceGeometry out = face_geometry(output_V, F);
    const FaceGeometry in = face_geometry(input_V, F);
    const FaceGeometry ref = face_geometry(reference_V, F);
    FlipTransitions t;
    for (Eigen::Index f = 0; f < F.rows(); ++f) {
        const bool flipped_in = in.normals.row(f).dot(ref.normals.row(f)) < 0.0;
        const bool flipped_out = out.normals.row(f).dot(ref.normals.row(f)) < 0.0;
        t.input += flipped_in ? 1 : 0;
        t.output += flipped_out ? 1 : 0;
        t.created += (flipped_out && !flipped_in) ? 1 : 0;
        t.kept += (flipped_out && flipped_in) ? 1 : 0;
        t.fixed += (flipped_in && !flipped_out) ? 1 : 0;
    }
    return t;
}

double signed_volume(const Vertices& V, const Faces& F) {
    double sum = 0.0;
    for (Eigen::Index f = 0; f < F.rows(); ++f) {
        const Eigen::Vector3d a = V.row(F(f, 0));
        const Eigen::Vector3d b = V.row(F(f, 1));
        const Eigen::Vector3d c = V.row(F(f, 2));
        sum += a.dot(b.cross(c));
    }
    return sum / 6.0;
}

MeshComparison compare_meshes(const Vertices& V,
                              const Faces& F,
                              const Vertices& reference_V,
                              const Faces& reference_F) {
    validate_mesh(V, F);
    validate_mesh(reference_V, reference_F);
    require_same_triangulation(V, F, reference_V, reference_F);
    MeshComparison out;
    const TriangleTree tree(reference_V, reference_F);
    out.vertex_error = vertex_error(V, F, tree);
    out.msae_deg = mean_angle_error_deg(V, F, reference_V, reference_F);
    out.quality = mesh_quality(V, F);
    out.reference_quality = mesh_quality(reference_V, reference_F);
    out.flipped_faces = flipped_faces(V, F, reference_V, reference_F);
    out.volume = signed_volume(V, F);
    out.reference_volume = signed_volume(reference_V, reference_F);
    out.volume_change = out.reference_volume != 0.0
                            ? (out.volume - out.reference_volume) / std::abs(out.reference_volume)
                            : 0.0;
    const Adjacency adj = build_adjacency(F, static_cast<int>(V.rows()));
    out.closed = adj.boundary_edges == 0 && adj.nonmanifold_edges == 0;
    return out;
}

}  // namespace octshape::mesh
