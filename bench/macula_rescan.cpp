// Simulated re-scans (issue 3, docs/algorithms/cube.md "Repeatability"): EYES phantom eyes,
// each scanned REPEATS times, then ICC(2,1) with its 95 % CI of every CuBe parameter over the
// EYES x REPEATS matrix (retina/stats.h), beside the thesis' Table 7.1 values (30 real eyes,
// 3 scans each). The eyes differ as people's do: Bezier and Scheibe families alternating, OD/OS
// alternating, thickness offset +-30 um, pit depth x0.8-1.2, pit width x0.85-1.15.
//  * Volume (default): each re-scan a fresh lateral shift of the fovea (uniform within +-100 um
//    in x and y around the eye's own position), a fresh rotation of the eye against the scan
//    grid (uniform within +-3 deg), fresh segmentation noise of 1 axial pixel and a fresh BM
//    tilt.
//  * Radial (--pattern radial --lines N; issue 20): each re-scan a star of N lines of 6 mm
//    (ASCANS A-scans each) aimed at the fovea: the fovea a fresh crossing offset from the
//    crossing (uniform over the disc of radius --max-offset-um, default 150 um, in a uniform
//    direction), the line set freshly rotated against the eye (uniform over one whole angular
//    step 180/N deg, i.e. every phase of the star, plus +-3 deg of cyclotorsion), fresh noise
//    and BM tilt as for a volume. The same eyes and tilts as the volume run. A second
//    table gives each parameter's within-eye SD in bins of the crossing offset (what the
//    offset costs), a third the RMS error against the truth in those bins.
// Usage: macula_rescan [EYES [REPEATS [ASCANS [BSCANS]]]] [--pattern volume|radial]
//                      [--lines N] [--max-offset-um D] [--noise-px S]
//        (default 20 10 768 61, 12 lines, 150 um, 1 px = 3.87 um of thickness noise)

#include <algorithm>
#include <ctime>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <numbers>
#include <random>
#include <stdexcept>
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

struct Options {
    int eyes = 20;
    int repeats = 10;
    int ascans = 768;
    int bscans = 61;
    bool radial = false;
    int lines = 12;
    double max_offset_um = 150.0;
    double noise_px = 1.0;  // SD of the thickness noise in axial pixels (3.87 um)
};

Options parse(int argc, char** argv) {
    Options o;
    std::vector<std::string> pos;
    for (int i = 1; i < argc; ++i) {
        const std::string a = argv[i];
        if (a.rfind("--", 0) != 0) {
            pos.push_back(a);
            continue;
        }
        if (i + 1 >= argc) throw std::invalid_argument(a + " needs a value");
        const std::string v = argv[++i];
        if (a == "--pattern") {
            if (v != "volume" && v != "radial") throw std::invalid_argument("--pattern " + v);
            o.radial = v == "radial";
        } else if (a == "--lines") {
            o.lines = std::max(3, std::atoi(v.c_str()));
        } else if (a == "--max-offset-um") {
            o.max_offset_um = std::clamp(std::atof(v.c_str()), 0.0, 1000.0);
        } else if (a == "--noise-px") {
            o.noise_px = std::clamp(std::atof(v.c_str()), 0.0, 10.0);
        } else {
            throw std::invalid_argument("unknown option " + a);
        }
    }
    if (pos.size() > 0) o.eyes = std::max(2, std::atoi(pos[0].c_str()));
    if (pos.size() > 1) o.repeats = std::max(2, std::atoi(pos[1].c_str()));
    if (pos.size() > 2) o.ascans = std::max(64, std::atoi(pos[2].c_str()));
    if (pos.size() > 3) o.bscans = std::max(8, std::atoi(pos[3].c_str()));
    return o;
}

// Truth of parameter `name` (NaN where the truth has none, e.g. rmse_um).
double truth_of(const std::string& name, const MaculaTruth& t) {
    if (name == "pit_depth_mm") return t.pit_depth_mm;
    if (name == "cft_mm") return t.cft_mm;
    if (name == "rim_height_mm") return t.rim_height_mm;
    if (name == "rim_diameter_mm") return t.rim.diameter_mm;
    if (name == "rim_disk_area_mm2") return t.rim.area_mm2;
    if (name == "rim_disk_major_mm2") return t.rim.eigenvalues_mm2[0];
    if (name == "rim_disk_minor_mm2") return t.rim.eigenvalues_mm2[1];
    if (name == "slope_diameter_mm") return t.slope.diameter_mm;
    if (name == "slope_disk_area_mm2") return t.slope.area_mm2;
    if (name == "slope_disk_major_mm2") return t.slope.eigenvalues_mm2[0];
    if (name == "slope_disk_minor_mm2") return t.slope.eigenvalues_mm2[1];
    if (name == "pit_flat_diameter_mm") return t.pit_flat_diameter_mm;
    if (name == "pit_flat_disk_area_mm2") return t.pit_flat.area_mm2;
    if (name == "pit_flat_disk_major_mm2") return t.pit_flat.eigenvalues_mm2[0];
    if (name == "pit_flat_disk_minor_mm2") return t.pit_flat.eigenvalues_mm2[1];
    if (name == "rim_volume_mm3") return t.rim_volume_mm3;
    if (name == "inner_rim_volume_mm3") return t.inner_rim_volume_mm3;
    if (name == "pit_volume_mm3") return t.pit_volume_mm3;
    if (name == "max_pit_slope_deg") return t.max_pit_slope_deg;
    if (name == "alpha_mean_mm") return t.alpha_mean_mm.value_or(std::nan(""));
    if (name == "beta_mean_mm") return t.beta_mean_mm.value_or(std::nan(""));
    return std::nan("");
}

}  // namespace

// Long (211 lines, over the 150 of the style) on purpose: the benchmark's protocol, read top to
// bottom against the ICC tables it prints; it ships no result. (Its table printing repeats
// onh_rescan.cpp's: a later change can share it.)
int main(int argc, char** argv) {
    Options o;
    try {
        o = parse(argc, argv);
    } catch (const std::exception& ex) {
        std::fprintf(stderr, "macula_rescan: %s\n", ex.what());
        return 64;
    }
    const int eyes = o.eyes;
    const int repeats = o.repeats;
    const auto& params = parameters();
    std::vector<Eigen::MatrixXd> m(params.size(), Eigen::MatrixXd(eyes, repeats));
    std::vector<Eigen::MatrixXd> err(params.size(), Eigen::MatrixXd(eyes, repeats));
    Eigen::MatrixXd offset_um(eyes, repeats);  // true |fovea - crossing| of each radial scan
    int flagged = 0;                           // radial scans with "centre off the line crossing"
    std::mt19937_64 rng(20261122);
    std::mt19937_64 radial_rng(20261203);
    auto uniform = [&](double lo, double hi) {
        return std::uniform_real_distribution<double>(lo, hi)(rng);
    };
    const double sigma_um = 3.8717 * o.noise_px;  // thickness noise (default 1 axial pixel)
    double analysis_ms = 0.0;
    int failures = 0;
    for (int e = 0; e < eyes; ++e) {
        MaculaPhantomParams eye;
        eye.family = e % 2 == 0 ? MaculaFamily::kBezier : MaculaFamily::kScheibe;
        eye.eye = (e / 2) % 2 == 0 ? octshape::io::Laterality::kOD : octshape::io::Laterality::kOS;
        eye.size_x = o.ascans;
        eye.num_bscans = o.bscans;
        eye.pixels = false;
        eye.noise_um = sigma_um / std::sqrt(2.0);  // on ILM and on BM: sigma on ILM - BM
        eye.thickness_offset_mm = uniform(-0.03, 0.03);
        eye.pit_depth_scale = uniform(0.8, 1.2);
        eye.radial_scale = uniform(0.85, 1.15);
        // The eye's own position on a volume's grid (drawn for radial runs too: the same eyes).
        const double x0 = uniform(-0.2, 0.2);
        const double y0 = uniform(-0.2, 0.2);
        if (o.radial) {
            eye.radial = true;
            eye.radial_lines = o.lines;
            eye.line_length_mm = 6.0;
        }
        for (int k = 0; k < repeats; ++k) {
            MaculaPhantomParams scan = eye;
            // The volume's draws always come first, from `rng`, so that a radial run has the
            // volume run's eyes and BM tilts; the radial placement has its own generator.
            scan.fovea_dx_mm = x0 + uniform(-0.1, 0.1);
            scan.fovea_dy_mm = y0 + uniform(-0.1, 0.1);
            scan.rotation_deg = uniform(-3.0, 3.0);
            scan.tilt_x = uniform(-0.03, 0.03);
            scan.tilt_y = uniform(-0.03, 0.03);
            offset_um(e, k) = std::nan("");
            if (o.radial) {
                auto uniform_radial = [&](double lo, double hi) {
                    return std::uniform_real_distribution<double>(lo, hi)(radial_rng);
                };
                // Uniform over the disc of radius max_offset (area-uniform radius).
                const double d = 1e-3 * o.max_offset_um * std::sqrt(uniform_radial(0.0, 1.0));
                const double phi = uniform_radial(0.0, 2.0 * std::numbers::pi);
                scan.fovea_dx_mm = d * std::cos(phi);
                scan.fovea_dy_mm = d * std::sin(phi);
                offset_um(e, k) = 1e3 * d;
                const double half_step = 90.0 / o.lines;
                scan.rotation_deg =
                    uniform_radial(-half_step, half_step) + uniform_radial(-3.0, 3.0);
            }
            scan.seed = static_cast<std::uint64_t>(1000 * e + k + 1);
            const MaculaPhantom ph = make_macula_phantom(scan);
            // Process CPU time (the benches share a loaded machine: wall time is not the
            // analysis's).
            const std::clock_t t0 = std::clock();
            const CubeResult r = analyse_macula(ph.scan);
            analysis_ms += 1e3 * static_cast<double>(std::clock() - t0) / CLOCKS_PER_SEC;
            if (std::find(r.qc_flags.begin(), r.qc_flags.end(), "centre off the line crossing") !=
                r.qc_flags.end()) {
                ++flagged;
            }
            for (std::size_t i = 0; i < params.size(); ++i) {
                const double v = params[i].get(r);
                if (!std::isfinite(v)) {
                    if (++failures == 1 || i == 0) {  // the first, with the analysis's notes
                        double rim_max = 0.0;
                        for (const auto& h : ph.truth.half_lines) {
                            rim_max = std::max(rim_max, h.rim_radius_mm);
                        }
                        std::fprintf(stderr, "eye %d scan %d: %s missing (largest true rim "
                                     "radius %.3f mm)\n", e, k, params[i].name, rim_max);
                        for (const std::string& n : r.notes) std::fprintf(stderr, "  %s\n", n.c_str());
                    } else if (failures <= 20) {
                        std::fprintf(stderr, "eye %d scan %d: %s missing\n", e, k, params[i].name);
                    }
                }
                m[i](e, k) = v;
                err[i](e, k) = v - truth_of(params[i].name, ph.truth);
            }
        }
    }
    if (o.radial) {
        std::printf("%d eyes x %d re-scans, radial %d lines x %d A-scans (6 mm), noise %.2f um, "
                    "crossing offset uniform over a %.0f um disc, line set rotated over one "
                    "step (%.1f deg) +-3 deg; analysis %.1f ms CPU per scan; %d of %d scans flagged "
                    "'centre off the line crossing'; %d missing values\n",
                    eyes, repeats, o.lines, o.ascans, sigma_um, o.max_offset_um, 180.0 / o.lines,
                    analysis_ms / (static_cast<double>(eyes) * repeats), flagged, eyes * repeats,
                    failures);
    } else {
        std::printf("%d eyes x %d re-scans, %d x %d (A-scans x B-scans), noise %.2f um, "
                    "shift +-100 um, rotation +-3 deg; analysis %.1f ms CPU per scan; %d missing "
                    "values\n",
                    eyes, repeats, o.ascans, o.bscans, sigma_um,
                    analysis_ms / (static_cast<double>(eyes) * repeats), failures);
    }
    std::printf("%-24s %8s %8s %8s %12s %12s %8s\n", "parameter", "ICC", "lower", "upper",
                "within_SD", "between_SD", "thesis");
    std::vector<Eigen::MatrixXd> resid(params.size());
    bool no_icc = false;  // a parameter with fewer than 2 complete eyes
    for (std::size_t i = 0; i < params.size(); ++i) {
        if (!m[i].allFinite()) {
            // ICC(2,1) needs a complete matrix: an eye with a missing value is dropped for
            // that parameter (and named), and its within-eye deviations count as zero below.
            std::vector<int> keep;
            for (int e = 0; e < eyes; ++e) {
                if (m[i].row(e).allFinite()) keep.push_back(e);
            }
            if (keep.size() < 2) {
                std::printf("%-24s (missing values)\n", params[i].name);
                no_icc = true;
                continue;
            }
            std::printf("%-24s (eyes with a missing value dropped: %d)\n", params[i].name,
                        eyes - static_cast<int>(keep.size()));
            Eigen::MatrixXd sub(static_cast<Eigen::Index>(keep.size()), repeats);
            for (std::size_t r = 0; r < keep.size(); ++r) {
                sub.row(static_cast<Eigen::Index>(r)) = m[i].row(keep[r]);
            }
            const IccResult icc = icc_2_1(sub);
            const Eigen::VectorXd mean = sub.rowwise().mean();
            const double n_eyes = static_cast<double>(keep.size());
            const double within =
                std::sqrt((sub.colwise() - mean).array().square().sum() / (n_eyes * (repeats - 1.0)));
            const double between =
                std::sqrt((mean.array() - mean.mean()).square().sum() / (n_eyes - 1.0));
            std::printf("%-24s %8.4f %8.4f %8.4f %12.4g %12.4g %8.4f\n", "", icc.icc, icc.lower,
                        icc.upper, within, between, params[i].thesis_icc);
            resid[i] = Eigen::MatrixXd::Zero(eyes, repeats);
            for (const int e : keep) resid[i].row(e) = m[i].row(e).array() - m[i].row(e).mean();
            continue;
        }
        const IccResult icc = icc_2_1(m[i]);
        // Within-eye SD: root mean within-row variance; between-eye SD: SD of the row means.
        const Eigen::VectorXd mean = m[i].rowwise().mean();
        resid[i] = m[i].colwise() - mean;
        const double within =
            std::sqrt(resid[i].array().square().sum() / (eyes * (repeats - 1.0)));
        const double between = std::sqrt((mean.array() - mean.mean()).square().sum() / (eyes - 1.0));
        std::printf("%-24s %8.4f %8.4f %8.4f %12.4g %12.4g %8.4f\n", params[i].name, icc.icc,
                    icc.lower, icc.upper, within, between, params[i].thesis_icc);
    }
    if (o.radial) {
        // What the crossing offset costs: per bin of the true offset, the RMS of the deviations
        // from the eye's mean (scaled by REPEATS / (REPEATS - 1), as the within-eye SD above:
        // that mean carries the eye's own offset bias) and the RMS error against the truth
        // (NaN where the truth has none).
        const std::vector<double> edges{0.0, 50.0, 100.0, 150.0, 1e9};
        const double scale = repeats / (repeats - 1.0);
        for (const bool truth : {false, true}) {
            std::printf("\n%s by crossing offset (um; scans per bin in the header)\n",
                        truth ? "RMS error vs truth" : "within-eye SD");
            std::printf("%-24s", "parameter");
            for (std::size_t b = 0; b + 1 < edges.size(); ++b) {
                if (edges[b] >= o.max_offset_um) break;
                int n = 0;
                for (int e = 0; e < eyes; ++e) {
                    for (int k = 0; k < repeats; ++k) {
                        n += offset_um(e, k) >= edges[b] && offset_um(e, k) < edges[b + 1];
                    }
                }
                std::printf(" %5.0f-%-3.0f(%3d)", edges[b], std::min(edges[b + 1], 999.0), n);
            }
            std::printf("\n");
            for (std::size_t i = 0; i < params.size(); ++i) {
                if (resid[i].size() == 0) continue;
                std::printf("%-24s", params[i].name);
                for (std::size_t b = 0; b + 1 < edges.size(); ++b) {
                    if (edges[b] >= o.max_offset_um) break;
                    double sum = 0.0;
                    int n = 0;
                    for (int e = 0; e < eyes; ++e) {
                        for (int k = 0; k < repeats; ++k) {
                            if (offset_um(e, k) < edges[b] || offset_um(e, k) >= edges[b + 1]) {
                                continue;
                            }
                            const double x = truth ? err[i](e, k) : resid[i](e, k);
                            if (!std::isfinite(x)) continue;  // a missing value
                            sum += x * x;
                            ++n;
                        }
                    }
                    const double v = n == 0 ? std::nan("")
                                     : std::sqrt((truth ? 1.0 : scale) * sum / n);
                    std::printf(" %15.4g", v);
                }
                std::printf("\n");
            }
        }
    }
    // A volume run has no missing value (its check); a radial half-line that fails under
    // noise omits that scan's 3-D parameters (the analysis's documented outcome), which only
    // drops its eye from those ICCs: an error only when a parameter has no ICC at all.
    return no_icc || (!o.radial && failures > 0) ? 1 : 0;
}
