#pragma once
// Statistical shape analysis (thesis §8.2): closest-point correspondences on aligned surfaces,
// the mean shape (Eq. 8.25) and the per-vertex standard deviation. The rigid alignment (ICP)
// is done beforehand by the caller (io/registration.h uses VTK's ICP); this part is Eigen only.
// docs/algorithms/meanshape.md.

#include <vector>

#include <Eigen/Core>

#include "octshape/mesh/mesh.h"

namespace octshape::mesh {

// A triangle surface already aligned to the reference.
struct Surface {
    Vertices V;  // #V×3
    Faces F;     // #F×3
};

struct MeanShapeParams {
    int threads = 1;  // std::threads for the closest-point queries; results do not depend on it

    // Throws UsageError naming the first bad field.
    void validate() const;
};

struct MeanShapeResult {
    // #V_ref×3 mean shape: v_j^s = (v_j + Σ_{i=1}^{n_s−1} c_ij) / n_s (Eq. 8.25 averaging all
    // n_s surfaces, the reference included), where c_ij is the point of surface i closest to
    // reference vertex v_j (on the surface, not only at its vertices). Faces: the reference's.
    Vertices mean;
    // #V_ref per-vertex standard deviation of the n_s corresponding points about the mean,
    // sd_j = sqrt( Σ_i |c_ij − v_j^s|² / n_s ) (population form, c_0j = v_j). For points that
    // scatter with SD σ along one direction, E[sd_j²] = σ² (n_s − 1) / n_s.
    Eigen::VectorXd sd;
    // Per surface (n_s entries, the reference first with 0): mean and RMS of |c_ij − v_j|, the
    // correspondence distances to the reference (length unit).
    std::vector<double> mean_distance;
    std::vector<double> rms_distance;
    int surfaces = 0;  // n_s
};

// `reference` is surface 0; `others` are surfaces 1 … n_s−1, aligned to it. Throws
// DataError for an invalid mesh (validate_mesh) or a surface without faces.
[[nodiscard]] MeanShapeResult mean_shape(const Surface& reference,
                                         const std::vector<Surface>& others,
                                         const MeanShapeParams& params = {});

}  // namespace octshape::mesh
