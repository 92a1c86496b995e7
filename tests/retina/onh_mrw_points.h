#pragma once
// The 3-D MRW per BMO point against a phantom's truth (issue 32 item 4), shared by the volume
// (onh_test.cpp) and radial (onh_radial_test.cpp) ONH tests; the bounds are argued where they
// are asserted.

#include <algorithm>
#include <cmath>
#include <cstddef>

#include "octshape/retina/onh.h"
#include "octshape/retina/phantom_onh.h"

namespace octshape::retina {

struct MrwPointErrors {
    double worst_mm = 0.0;       // largest |measured - true| over the resampled points
    double jump_mm = 0.0;        // largest |MRW_i+1 - MRW_i| between neighbouring points
    double truth_jump_mm = 0.0;  // the same of the truth's points (the geometry's own)
};

// Each measured point against the truth's point at the nearest anatomical angle (both sets are
// uniform in their ellipse's parameter angle, 1 deg apart at 360 points: the match is off by
// <= ~0.6 deg, which moves the true MRW by <= truth_jump_mm).
inline MrwPointErrors mrw_point_errors(const OnhResult& r, const OnhTruth& t) {
    MrwPointErrors e;
    const std::size_t n = r.mrw_mm.size();
    const std::size_t m = t.mrw_mm.size();
    for (std::size_t j = 0; j < m; ++j) {
        e.truth_jump_mm = std::max(e.truth_jump_mm, std::fabs(t.mrw_mm[(j + 1) % m] - t.mrw_mm[j]));
    }
    for (std::size_t i = 0; i < n; ++i) {
        std::size_t best = 0;
        double best_deg = 360.0;
        for (std::size_t j = 0; j < m; ++j) {
            const double d =
                std::fmod(std::fabs(r.bmo_anatomical_deg[i] - t.bmo_anatomical_deg[j]), 360.0);
            if (std::min(d, 360.0 - d) < best_deg) {
                best_deg = std::min(d, 360.0 - d);
                best = j;
            }
        }
        e.worst_mm = std::max(e.worst_mm, std::fabs(r.mrw_mm[i] - t.mrw_mm[best]));
        e.jump_mm = std::max(e.jump_mm, std::fabs(r.mrw_mm[(i + 1) % n] - r.mrw_mm[i]));
    }
    return e;
}

}  // namespace octshape::retina
