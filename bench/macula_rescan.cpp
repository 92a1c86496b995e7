// Simulated re-scans (issue 3, docs/algorithms/cube.md "Repeatability"): EYES phantom eyes,
// each scanned REPEATS times with a fresh lateral shift of the fovea (uniform within +-100 um in
// x and y around the eye's own position), a fresh rotation of the eye against the scan grid
// (uniform within +-3 deg), fresh segmentation noise of 1 axial pixel and a fresh BM tilt; then
// ICC(2,1) with its 95 % CI of every CuBe parameter over the EYES x REPEATS matrix
// (retina/stats.h), beside the thesis' Table 7.1 values (30 real eyes, 3 scans each).
// The eyes differ as people's do: Bezier and Scheibe families alternating, OD/OS alternating,
// thickness offset +-30 um, pit depth x0.8-1.2, pit width x0.85-1.15.
// Usage: macula_rescan [EYES [REPEATS [ASCANS [BSCANS]]]]   (default 20 10 768 61)

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <random>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "octshape/retina/cube.h"
#include "octshape/retina/phantom_macula.h"
#include "octshape/retina/stats.h"

namespace {

using namespace octshape::retina;

struct Parameter {
    const char* name;
    double thesis_icc;  // Table 7.1; NaN where the thesis has no row
    std::function<double(const CubeResult&)> get;
};

const std::vector<Parameter>& parameters() {
    const double na = std::nan("");
    static const std::vector<Parameter> p{
        {"pit_depth_mm", 0.9813, [](const CubeResult& r) { return r.pit_depth_mm; }},
        {"cft_mm", 0.9894, [](const CubeResult& r) { return r.cft_mm; }},
        {"rim_height_mm", 0.9762, [](const CubeResult& r) { return r.rim_height_mm; }},
        {"rim_diameter_mm", 0.9250, [](const CubeResult& r) { return r.rim.diameter_mm; }},
        {"rim_disk_area_mm2", 0.9192, [](const CubeResult& r) { return r.rim.area_mm2; }},
        {"rim_disk_major_mm2", 0.9099,
         [](const CubeResult& r) { return r.rim.eigenvalues_mm2[0]; }},
        {"rim_disk_minor_mm2", 0.9069,
         [](const CubeResult& r) { return r.rim.eigenvalues_mm2[1]; }},
        {"slope_diameter_mm", 0.9309, [](const CubeResult& r) { return r.slope.diameter_mm; }},
        {"slope_disk_area_mm2", 0.9467, [](const CubeResult& r) { return r.slope.area_mm2; }},
        {"slope_disk_major_mm2", 0.9365,
         [](const CubeResult& r) { return r.slope.eigenvalues_mm2[0]; }},
        {"slope_disk_minor_mm2", 0.9467,
         [](const CubeResult& r) { return r.slope.eigenvalues_mm2[1]; }},
        {"pit_flat_diameter_mm", 0.8966,
         [](const CubeResult& r) { return r.pit_flat_diameter_mm; }},
        {"pit_flat_disk_area_mm2", 0.9155,
         [](const CubeResult& r) { return r.pit_flat.area_mm2; }},
        {"pit_flat_disk_major_mm2", 0.8990,
         [](const CubeResult& r) { return r.pit_flat.eigenvalues_mm2[0]; }},
        {"pit_flat_disk_minor_mm2", 0.9135,
         [](const CubeResult& r) { return r.pit_flat.eigenvalues_mm2[1]; }},
        {"rim_volume_mm3", 0.8957, [](const CubeResult& r) { return r.rim_volume_mm3; }},
        {"inner_rim_volume_mm3", 0.9668,
         [](const CubeResult& r) { return r.inner_rim_volume_mm3; }},
        {"pit_volume_mm3", 0.9606, [](const CubeResult& r) { return r.pit_volume_mm3; }},
        {"max_pit_slope_deg", 0.9697, [](const CubeResult& r) { return r.max_pit_slope_deg; }},
        {"alpha_mean_mm", 0.9172, [](const CubeResult& r) { return r.alpha_mean_mm; }},
        {"beta_mean_mm", 0.8102, [](const CubeResult& r) { return r.beta_mean_mm; }},
        {"rmse_um", na, [](const CubeResult& r) { return r.rmse_um; }},
    };
    return p;
}

}  // namespace

int main(int argc, char** argv) {
    const int eyes = argc > 1 ? std::max(2, std::atoi(argv[1])) : 20;
    const int repeats = argc > 2 ? std::max(2, std::atoi(argv[2])) : 10;
    const int ascans = argc > 3 ? std::max(64, std::atoi(argv[3])) : 768;
    const int bscans = argc > 4 ? std::max(8, std::atoi(argv[4])) : 61;
    const auto& params = parameters();
    std::vector<Eigen::MatrixXd> m(params.size(), Eigen::MatrixXd(eyes, repeats));
    std::mt19937_64 rng(20261122);
    auto uniform = [&](double lo, double hi) {
        return std::uniform_real_distribution<double>(lo, hi)(rng);
    };
    const double sigma_um = 3.8717;  // 1 axial pixel of thickness noise
    double analysis_ms = 0.0;
    int failures = 0;
    for (int e = 0; e < eyes; ++e) {
        MaculaPhantomParams eye;
        eye.family = e % 2 == 0 ? MaculaFamily::kBezier : MaculaFamily::kScheibe;
        eye.eye = (e / 2) % 2 == 0 ? octshape::io::Laterality::kOD : octshape::io::Laterality::kOS;
        eye.size_x = ascans;
        eye.num_bscans = bscans;
        eye.pixels = false;
        eye.noise_um = sigma_um / std::sqrt(2.0);  // on ILM and on BM: sigma on ILM - BM
        eye.thickness_offset_mm = uniform(-0.03, 0.03);
        eye.pit_depth_scale = uniform(0.8, 1.2);
        eye.radial_scale = uniform(0.85, 1.15);
        const double x0 = uniform(-0.2, 0.2);
        const double y0 = uniform(-0.2, 0.2);
        for (int k = 0; k < repeats; ++k) {
            MaculaPhantomParams scan = eye;
            scan.fovea_dx_mm = x0 + uniform(-0.1, 0.1);
            scan.fovea_dy_mm = y0 + uniform(-0.1, 0.1);
            scan.rotation_deg = uniform(-3.0, 3.0);
            scan.tilt_x = uniform(-0.03, 0.03);
            scan.tilt_y = uniform(-0.03, 0.03);
            scan.seed = static_cast<std::uint64_t>(1000 * e + k + 1);
            const MaculaPhantom ph = make_macula_phantom(scan);
            const auto t0 = std::chrono::steady_clock::now();
            const CubeResult r = analyse_macula(ph.scan);
            analysis_ms += std::chrono::duration<double, std::milli>(
                               std::chrono::steady_clock::now() - t0)
                               .count();
            for (std::size_t i = 0; i < params.size(); ++i) {
                const double v = params[i].get(r);
                if (!std::isfinite(v)) ++failures;
                m[i](e, k) = v;
            }
        }
    }
    std::printf("%d eyes x %d re-scans, %d x %d (A-scans x B-scans), noise %.2f um, "
                "shift +-100 um, rotation +-3 deg; analysis %.1f ms per scan; %d missing values\n",
                eyes, repeats, ascans, bscans, sigma_um,
                analysis_ms / (static_cast<double>(eyes) * repeats), failures);
    std::printf("%-24s %8s %8s %8s %12s %12s %8s\n", "parameter", "ICC", "lower", "upper",
                "within_SD", "between_SD", "thesis");
    for (std::size_t i = 0; i < params.size(); ++i) {
        if (!m[i].allFinite()) {
            std::printf("%-24s (missing values)\n", params[i].name);
            continue;
        }
        const IccResult icc = icc_2_1(m[i]);
        // Within-eye SD: root mean within-row variance; between-eye SD: SD of the row means.
        const Eigen::VectorXd mean = m[i].rowwise().mean();
        const double within =
            std::sqrt((m[i].colwise() - mean).array().square().sum() / (eyes * (repeats - 1.0)));
        const double between = std::sqrt((mean.array() - mean.mean()).square().sum() / (eyes - 1.0));
        std::printf("%-24s %8.4f %8.4f %8.4f %12.4g %12.4g %8.4f\n", params[i].name, icc.icc,
                    icc.lower, icc.upper, within, between, params[i].thesis_icc);
    }
    return failures == 0 ? 0 : 1;
}
