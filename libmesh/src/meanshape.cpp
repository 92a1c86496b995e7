#include "octshape/mesh/meanshape.h"

#include <cmath>
#include <stdexcept>
#include <string>

#include "octshape/error.h"
#include "octshape/mesh/closest_point.h"
#include "parallel.h"

namespace octshape::mesh {

void MeanShapeParams::validate() const {
    if (threads < 1) throw UsageError("threads must be >= 1");
}

MeanShapeResult mean_shape(const Surface& reference,
                           const std::vector<Surface>& others,
                           const MeanShapeParams& params) {
    params.validate();
    validate_mesh(reference.V, reference.F);
    const int nv = static_cast<int>(reference.V.rows());
    const int ns = static_cast<int>(others.size()) + 1;
    // Correspondences C(i) (#V_ref×3) on every other surface, §8.2.1.
    std::vector<Vertices> C;
    C.reserve(others.size());
    for (std::size_t s = 0; s < others.size(); ++s) {
        if (others[s].F.rows() == 0) {
            throw DataError("surface " + std::to_string(s + 1) + " has no face");
        }
        const TriangleTree tree(others[s].V, others[s].F);  // validates the mesh
        Vertices c(nv, 3);
        detail::parallel_for(nv, params.threads, [&](int begin, int end) {
            for (int j = begin; j < end; ++j) {
                c.row(j) = tree.closest(reference.V.row(j).transpose()).point.transpose();
            }
        });
        C.push_back(std::move(c));
    }
    MeanShapeResult out;
    out.surfaces = ns;
    // Eq. 8.25: the centroid of the n_s corresponding points (the reference vertex included).
    out.mean = reference.V;
    for (const auto& c : C) out.mean += c;
    out.mean /= static_cast<double>(ns);
    Eigen::VectorXd ss = (reference.V - out.mean).rowwise().squaredNorm();
    for (const auto& c : C) ss += (c - out.mean).rowwise().squaredNorm();
    out.sd = (ss / static_cast<double>(ns)).cwiseSqrt();
    out.mean_distance.assign(1, 0.0);
    out.rms_distance.assign(1, 0.0);
    for (const auto& c : C) {
        const Eigen::VectorXd d2 = (c - reference.V).rowwise().squaredNorm();
        out.mean_distance.push_back(nv > 0 ? d2.cwiseSqrt().mean() : 0.0);
        out.rms_distance.push_back(nv > 0 ? std::sqrt(d2.mean()) : 0.0);
    }
    return out;
}

}  // namespace octshape::mesh
