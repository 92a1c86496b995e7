#include "octshape/mesh/section.h"

#include <string>

#include "octshape/error.h"

namespace octshape::mesh {

std::vector<SectionSegment> zero_level_segments(const Vertices& V,
                                                const Faces& F,
                                                std::span<const double> values) {
    if (values.size() != static_cast<std::size_t>(V.rows())) {
        throw UsageError("zero_level_segments: " + std::to_string(values.size()) +
                         " values for " + std::to_string(V.rows()) + " vertices");
    }
    std::vector<SectionSegment> segs;
    for (Eigen::Index f = 0; f < F.rows(); ++f) {
        SectionSegment s;
        s.face = static_cast<int>(f);
        int hits = 0;
        for (int k = 0; k < 3 && hits < 2; ++k) {
            const int ia = F(f, k);
            const int ib = F(f, (k + 1) % 3);
            const double da = values[static_cast<std::size_t>(ia)];
            const double db = values[static_cast<std::size_t>(ib)];
            if ((da < 0.0) == (db < 0.0)) continue;
            const double t = da / (da - db);
            const Eigen::Vector3d p = V.row(ia) + t * (V.row(ib) - V.row(ia));
            (hits++ == 0 ? s.a : s.b) = p;
        }
        if (hits == 2) segs.push_back(s);
    }
    return segs;
}

std::vector<SectionSegment> plane_section(const Vertices& V,
                                          const Faces& F,
                                          const Eigen::Vector3d& normal,
                                          double offset) {
    std::vector<double> d(static_cast<std::size_t>(V.rows()));
    for (Eigen::Index v = 0; v < V.rows(); ++v) {
        d[static_cast<std::size_t>(v)] =
            normal.x() * V(v, 0) + normal.y() * V(v, 1) + normal.z() * V(v, 2) - offset;
    }
    return zero_level_segments(V, F, d);
}

}  // namespace octshape::mesh
