#pragma once
// Speckle of the vitreous of each B-scan (phantom tests of the acquisition artefacts).

#include <algorithm>
#include <cmath>

#include "octshape/io/scan.h"

namespace octshape::test {

// The largest |var / mean^2 x looks - 1| over the B-scans of their vitreous pixels (rows above
// the device ILM line less 2 px; constant reflectance there): 0 for pure Gamma(looks) speckle.
inline double worst_vitreous_speckle(const io::Scan& scan, int ilm_line, double looks) {
    const int nx = scan.meta.size_x;
    double worst = 0.0;
    for (int k = 0; k < scan.num_bscans(); ++k) {
        const auto& px = scan.bscans[static_cast<std::size_t>(k)].pixels;
        double s1 = 0.0;
        double s2 = 0.0;
        double n = 0.0;
        for (int a = 0; a < nx; ++a) {
            const float ilm = scan.depth_px(ilm_line, k, a);
            if (!io::is_valid(ilm)) continue;  // a missing A-scan
            const int top = static_cast<int>(std::floor(ilm)) - 2;
            for (int z = 0; z < top; ++z) {
                const double v = px[static_cast<std::size_t>(z * nx + a)];
                s1 += v;
                s2 += v * v;
                n += 1.0;
            }
        }
        const double mean = s1 / n;
        worst = std::max(worst, std::fabs((s2 / n - mean * mean) / (mean * mean) * looks - 1.0));
    }
    return worst;
}

}  // namespace octshape::test
