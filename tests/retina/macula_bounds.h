#pragma once
// Error bounds of the CuBe analysis that follow from how a macula phantom's surface is sampled,
// computed from the generator's own functions (phantom_macula.h), never from the analysis.

#include <algorithm>
#include <cmath>
#include <numbers>

#include "octshape/retina/phantom_macula.h"

namespace octshape::retina {

// Error bounds that follow from how the phantom surface T(r, theta) is sampled, computed from
// the generator's own function (not from the analysis).
struct SamplingBounds {
    double node_rise_mm = 0.0;     // delta: rise of T at the distance of the nearest grid node
    double centre_mm = 0.0;        // e: bound on the found centre's distance from the true one
    double bilinear_mm = 0.0;      // eps: bound on the bilinear interpolation error
    double rim_curv = 0.0;         // least |d2T/dr2| at the rims (1/mm)
    double rim_theta_slope = 0.0;  // max |d h_rim / d theta| (mm/rad)
    double min_rim_radius = 0.0;
};

inline SamplingBounds sampling_bounds(const MaculaPhantomParams& p,
                                      double dx,
                                      double dy,
                                      double tie) {
    SamplingBounds s;
    auto T = [&](double r, double th) { return macula_thickness_mm(p, r, th); };
    const double cft = T(0.0, 0.0);
    // The true centre is at most half a cell diagonal from a grid node.
    const double dn = 0.5 * std::hypot(dx, dy);
    for (int i = 0; i < 360; ++i) s.node_rise_mm = std::max(s.node_rise_mm, T(dn, i) - cft);
    // Every node the search can pick (value <= that node's value + tie) lies where T <= CFT +
    // delta + tie, i.e. within r_delta of the centre (T rises monotonically in the pit); a
    // component-wise median of such nodes lies in the bounding square: sqrt(2) r_delta.
    double r_delta = 0.0;
    for (int i = 0; i < 360; ++i) {
        double r = 0.0;
        while (T(r + 1e-4, i) - cft <= s.node_rise_mm + tie) r += 1e-4;
        r_delta = std::max(r_delta, r + 1e-4);
    }
    s.centre_mm = std::sqrt(2.0) * r_delta;
    // Bilinear error <= (dx^2 max|T_xx| + dy^2 max|T_yy|) / 8 within R + e of the centre:
    // second differences (h = 5 um) over a polar grid.
    double kmax = 0.0;
    const double h = 0.005;
    for (double r = 0.0; r <= 2.0 + s.centre_mm + 0.05; r += 0.01) {
        for (int i = 0; i < 360; i += 2) {
            const double x = r * std::cos(i / (180.0 / std::numbers::pi));
            const double y = r * std::sin(i / (180.0 / std::numbers::pi));
            auto at = [&](double u, double v) {
                return T(std::hypot(u, v), std::atan2(v, u) * (180.0 / std::numbers::pi));
            };
            const double c = at(x, y);
            kmax = std::max(kmax, std::fabs(at(x + h, y) - 2 * c + at(x - h, y)) / (h * h));
            kmax = std::max(kmax, std::fabs(at(x, y + h) - 2 * c + at(x, y - h)) / (h * h));
        }
    }
    s.bilinear_mm = (dx * dx + dy * dy) * kmax / 8.0;
    s.rim_curv = 1e9;
    s.min_rim_radius = 1e9;
    const MaculaTruth t = macula_truth(p);
    for (const auto& hl : t.half_lines) {
        const double r = hl.rim_radius_mm;
        const double th = hl.angle_deg;
        s.rim_curv = std::min(s.rim_curv, -(T(r + h, th) - 2 * T(r, th) + T(r - h, th)) / (h * h));
        s.min_rim_radius = std::min(s.min_rim_radius, r);
    }
    // Crest height along the rim ring h(theta) = T(r_rim(theta), theta), from the profiles.
    auto crest = [&](double th) {
        const double r = p.family == MaculaFamily::kBezier
                             ? bezier_profile(th, p.flat).rim_radius_mm
                             : scheibe_profile(th, p.flat).rim_radius_mm();
        return T(r, th);
    };
    for (int i = 0; i < 360; ++i) {
        s.rim_theta_slope = std::max(s.rim_theta_slope, std::fabs(crest(i + 0.5) - crest(i - 0.5)) *
                                                            (180.0 / std::numbers::pi));
    }
    return s;
}

}  // namespace octshape::retina
