#include "vertex_update.h"

namespace octshape::mesh::detail {

void vertex_step(const Vertices& V,
                 const Vertices& N,
                 const FaceGeometry& geometry,
                 const Adjacency& adjacency,
                 const std::vector<std::uint8_t>& fixed,
                 double lambda_i,
                 int begin,
                 int end,
                 Vertices& out) {
    const Csr& vf = adjacency.vertex_faces;
    const Csr& vv = adjacency.vertex_vertices;
    for (int i = begin; i < end; ++i) {
        const Eigen::Vector3d vi = V.row(i);
        if (fixed[static_cast<std::size_t>(i)] != 0 || vf.size(i) == 0) {
            out.row(i) = vi;
            continue;
        }
        Eigen::Vector3d step = Eigen::Vector3d::Zero();
        Eigen::Vector3d vertex_normal = Eigen::Vector3d::Zero();
        for (int p = vf.begin(i); p < vf.end(i); ++p) {
            const int k = vf.item(p);
            const Eigen::Vector3d nk = N.row(k);
            const Eigen::Vector3d ck = geometry.centroids.row(k);
            step += nk.dot(ck - vi) * nk;                 // Eq. 5.9 / 3.7, edge term
            vertex_normal += geometry.areas(k) * nk;      // Eq. 5.7
        }
        step /= static_cast<double>(vf.size(i));
        if (lambda_i != 0.0) {
            // Eq. 5.6: D_i = Σ w_ij v_j / Σ w_ij − v_i with w_ij = |v_i − v_j|².
            Eigen::Vector3d weighted = Eigen::Vector3d::Zero();
            double weight = 0.0;
            for (int p = vv.begin(i); p < vv.end(i); ++p) {
                const Eigen::Vector3d vj = V.row(vv.item(p));
                const double w = (vi - vj).squaredNorm();
                weighted += w * vj;
                weight += w;
            }
            if (weight > 0.0) {
                const Eigen::Vector3d d = weighted / weight - vi;
                // Eq. 5.7 normalised to unit length so that Eq. 5.8 is a true projection.
                const double len = vertex_normal.norm();
                const Eigen::Vector3d nv =
                    len > 0.0 ? Eigen::Vector3d(vertex_normal / len) : Eigen::Vector3d::Zero();
                const Eigen::Vector3d dt = d - d.dot(nv) * nv;  // Eq. 5.8
                step += lambda_i * (d + dt);                   // Eq. 5.5, 5.9
            }
        }
        out.row(i) = vi + step;
    }
}

}  // namespace octshape::mesh::detail
