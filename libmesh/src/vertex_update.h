#pragma once
// Private to libmesh: the vertex step shared by RoFi (Eq. 5.9) and ENVT (Eq. 3.7).

#include "octshape/mesh/mesh.h"

namespace octshape::mesh::detail {

// One Jacobi step for vertices [begin, end): out.row(i) from V, the filtered face normals N
// (#F×3, unit), the current face geometry and λ_I (0 = ENVT / plain orthogonality step).
//   v_i + 1/|F_v(i)| Σ_k (ñ_k·(c_k − v_i)) ñ_k + λ_I R_i
// which equals 1/(3|F_v(i)|) Σ_k Σ_{j∈f_k, j≠i} (ñ_k·(v_j − v_i)) ñ_k because
// Σ_{j∈f_k, j≠i} (v_j − v_i) = 3 (c_k − v_i). Fixed vertices are copied.
void vertex_step(const Vertices& V,
                 const Vertices& N,
                 const FaceGeometry& geometry,
                 const Adjacency& adjacency,
                 const std::vector<std::uint8_t>& fixed,
                 double lambda_i,
                 int begin,
                 int end,
                 Vertices& out);

}  // namespace octshape::mesh::detail
