// The crossing-offset table of radial macula scans (issue 20; docs/algorithms/cube.md "Error
// against the crossing offset"): noise-free radial phantoms (6 mm lines of ASCANS A-scans, the
// default analysis), the true fovea D um from the lines' crossing, D = 0, 25, ..., 150, in
// DIRS anatomical directions evenly spread over 360 deg (default 8: 0, 45, ..., 315 deg). Per
// family (Bezier, Scheibe), line count (12, 24) and offset, every parameter's largest error
// against the truth over the directions: lengths (and CFT, heights, alpha, beta) in um,
// areas, eigenvalues and volumes in % of the truth, the slope in deg. `*` marks an error above
// the volume analysis's target where the tests hold one (1 % of the value, lengths at least
// 2 um, slope 0.2 deg; Scheibe pit-flat diameter 17 %, the model's limit: tests/retina/
// cube_radial_test.cpp), and the last column is the largest tabulated offset up to which
// that parameter meets it in every direction. The last rows: the centre's error and the
// offset the analysis measures (radial.centre_offset_distance_mm, which raises the QC flag
// beyond radial.centre_offset_limit_mm), both the largest over the directions. OD only (OS
// is the mirror image: the same errors, tests/retina/cube_radial_test.cpp).
// Usage: macula_radial [DIRS [ASCANS]]   (default 8 768; ~30 s of one core)

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <functional>
#include <numbers>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "octshape/retina/cube.h"
#include "octshape/retina/phantom_macula.h"

namespace {

using namespace octshape::retina;

enum class Unit { kUm, kPercent, kDeg };

struct Parameter {
    const char* name;
    Unit unit;
    // The volume target (in the unit of the table) for a truth value, or NaN: no target.
    std::function<double(double truth, bool scheibe)> target;
    std::function<double(const CubeResult&)> get;
    std::function<double(const MaculaTruth&)> truth;
};

double length_target(double v, bool /*scheibe*/) { return 1e3 * std::max(0.01 * std::fabs(v), 0.002); }
double percent_target(double /*v*/, bool /*scheibe*/) { return 1.0; }
double no_target(double /*v*/, bool /*scheibe*/) { return std::nan(""); }

const std::vector<Parameter>& parameters() {
    using R = const CubeResult&;
    using T = const MaculaTruth&;
    static const std::vector<Parameter> p{
        {"pit_depth_mm", Unit::kUm, no_target, [](R r) { return r.pit_depth_mm; },
         [](T t) { return t.pit_depth_mm; }},
        {"cft_mm", Unit::kUm, length_target, [](R r) { return r.cft_mm; },
         [](T t) { return t.cft_mm; }},
        {"rim_height_mm", Unit::kUm, length_target, [](R r) { return r.rim_height_mm; },
         [](T t) { return t.rim_height_mm; }},
        {"rim_diameter_mm", Unit::kUm, length_target, [](R r) { return r.rim.diameter_mm; },
         [](T t) { return t.rim.diameter_mm; }},
        {"rim_disk_area_mm2", Unit::kPercent, percent_target, [](R r) { return r.rim.area_mm2; },
         [](T t) { return t.rim.area_mm2; }},
        {"rim_disk_major_mm2", Unit::kPercent, no_target,
         [](R r) { return r.rim.eigenvalues_mm2[0]; }, [](T t) { return t.rim.eigenvalues_mm2[0]; }},
        {"rim_disk_minor_mm2", Unit::kPercent, no_target,
         [](R r) { return r.rim.eigenvalues_mm2[1]; }, [](T t) { return t.rim.eigenvalues_mm2[1]; }},
        {"slope_diameter_mm", Unit::kUm, length_target, [](R r) { return r.slope.diameter_mm; },
         [](T t) { return t.slope.diameter_mm; }},
        {"slope_disk_area_mm2", Unit::kPercent, no_target, [](R r) { return r.slope.area_mm2; },
         [](T t) { return t.slope.area_mm2; }},
        {"slope_disk_major_mm2", Unit::kPercent, no_target,
         [](R r) { return r.slope.eigenvalues_mm2[0]; },
         [](T t) { return t.slope.eigenvalues_mm2[0]; }},
        {"slope_disk_minor_mm2", Unit::kPercent, no_target,
         [](R r) { return r.slope.eigenvalues_mm2[1]; },
         [](T t) { return t.slope.eigenvalues_mm2[1]; }},
        {"pit_flat_diameter_mm", Unit::kUm,
         [](double v, bool scheibe) { return scheibe ? 1e3 * 0.17 * v : length_target(v, false); },
         [](R r) { return r.pit_flat_diameter_mm; }, [](T t) { return t.pit_flat_diameter_mm; }},
        {"pit_flat_disk_area_mm2", Unit::kPercent, no_target,
         [](R r) { return r.pit_flat.area_mm2; }, [](T t) { return t.pit_flat.area_mm2; }},
        {"pit_flat_disk_major_mm2", Unit::kPercent, no_target,
         [](R r) { return r.pit_flat.eigenvalues_mm2[0]; },
         [](T t) { return t.pit_flat.eigenvalues_mm2[0]; }},
        {"pit_flat_disk_minor_mm2", Unit::kPercent, no_target,
         [](R r) { return r.pit_flat.eigenvalues_mm2[1]; },
         [](T t) { return t.pit_flat.eigenvalues_mm2[1]; }},
        {"rim_volume_mm3", Unit::kPercent, percent_target, [](R r) { return r.rim_volume_mm3; },
         [](T t) { return t.rim_volume_mm3; }},
        {"inner_rim_volume_mm3", Unit::kPercent, percent_target,
         [](R r) { return r.inner_rim_volume_mm3; }, [](T t) { return t.inner_rim_volume_mm3; }},
        {"pit_volume_mm3", Unit::kPercent, percent_target, [](R r) { return r.pit_volume_mm3; },
         [](T t) { return t.pit_volume_mm3; }},
        {"max_pit_slope_deg", Unit::kDeg, [](double, bool) { return 0.2; },
         [](R r) { return r.max_pit_slope_deg; }, [](T t) { return t.max_pit_slope_deg; }},
        {"alpha_mean_mm", Unit::kUm, no_target, [](R r) { return r.alpha_mean_mm; },
         [](T t) { return t.alpha_mean_mm.value_or(std::nan("")); }},
        {"beta_mean_mm", Unit::kUm, no_target, [](R r) { return r.beta_mean_mm; },
         [](T t) { return t.beta_mean_mm.value_or(std::nan("")); }},
    };
    return p;
}

// |error| in the parameter's table unit.
double error_in_unit(Unit u, double value, double truth) {
    switch (u) {
        case Unit::kUm: return 1e3 * std::fabs(value - truth);
        case Unit::kPercent: return 100.0 * std::fabs(value / truth - 1.0);
        case Unit::kDeg: return std::fabs(value - truth);
    }
    return std::nan("");
}

const char* unit_name(Unit u) {
    switch (u) {
        case Unit::kUm: return "um";
        case Unit::kPercent: return "%";
        case Unit::kDeg: return "deg";
    }
    return "";
}

}  // namespace

int main(int argc, char** argv) {
    const int dirs = argc > 1 ? std::max(1, std::atoi(argv[1])) : 8;
    const int ascans = argc > 2 ? std::max(128, std::atoi(argv[2])) : 768;
    const std::vector<double> offsets{0.0, 25.0, 50.0, 75.0, 100.0, 125.0, 150.0};
    const auto& params = parameters();
    int failures = 0;
    double cpu_ms = 0.0;
    int analyses = 0;
    for (const auto family : {MaculaFamily::kBezier, MaculaFamily::kScheibe}) {
        const bool scheibe = family == MaculaFamily::kScheibe;
        for (const int lines : {12, 24}) {
            // worst(i, j): parameter i's largest error at offset j; target: the smallest target
            // over the directions (the truth changes little with the direction).
            Eigen::MatrixXd worst = Eigen::MatrixXd::Zero(static_cast<Eigen::Index>(params.size()),
                                                          static_cast<Eigen::Index>(offsets.size()));
            std::vector<double> target(params.size(), std::nan(""));
            std::vector<double> centre_err(offsets.size(), 0.0);
            std::vector<double> measured(offsets.size(), 0.0);
            std::vector<int> flagged(offsets.size(), 0);
            double limit_mm = std::nan("");
            for (std::size_t j = 0; j < offsets.size(); ++j) {
                for (int d = 0; d < dirs; ++d) {
                    MaculaPhantomParams p;
                    p.family = family;
                    p.radial = true;
                    p.radial_lines = lines;
                    p.size_x = ascans;
                    p.pixels = false;
                    // OD: anatomical 0 deg (nasal) is grid +x.
                    const double th = 2.0 * std::numbers::pi * d / dirs;
                    p.fovea_dx_mm = 1e-3 * offsets[j] * std::cos(th);
                    p.fovea_dy_mm = 1e-3 * offsets[j] * std::sin(th);
                    const MaculaPhantom ph = make_macula_phantom(p);
                    const std::clock_t t0 = std::clock();
                    const CubeResult r = analyse_macula(ph.scan);
                    cpu_ms += 1e3 * static_cast<double>(std::clock() - t0) / CLOCKS_PER_SEC;
                    ++analyses;
                    limit_mm = r.radial.centre_offset_limit_mm;
                    // The truth frame's crossing is the field centre (L/2, L/2) = (3, 3) mm; the
                    // analysis reports the centre from the crossing.
                    centre_err[j] = std::max(
                        centre_err[j],
                        1e3 * (r.centre_mm + Eigen::Vector2d(3.0, 3.0) - ph.centre_mm).norm());
                    measured[j] = std::max(measured[j], 1e3 * r.radial.centre_offset_distance_mm);
                    flagged[j] += std::find(r.qc_flags.begin(), r.qc_flags.end(),
                                            "centre off the line crossing") != r.qc_flags.end();
                    for (std::size_t i = 0; i < params.size(); ++i) {
                        const double t = params[i].truth(ph.truth);
                        if (!std::isfinite(t)) {
                            worst(static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(j)) =
                                std::nan("");
                            continue;
                        }
                        const double v = params[i].get(r);
                        if (!std::isfinite(v)) ++failures;
                        const double e = error_in_unit(params[i].unit, v, t);
                        auto& w = worst(static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(j));
                        w = std::max(w, e);
                        const double tg = params[i].target(t, scheibe);
                        if (std::isfinite(tg)) {
                            target[i] = std::isfinite(target[i]) ? std::min(target[i], tg) : tg;
                        }
                    }
                }
            }
            std::printf("\n%s, %d lines (%d A-scans per 6 mm line), OD, worst of %d directions; "
                        "'*' above the volume target\n",
                        to_string(family).c_str(), lines, ascans, dirs);
            std::printf("%-24s %-4s %7s", "parameter", "unit", "target");
            for (const double off : offsets) std::printf(" %8.0f", off);
            std::printf(" %9s\n", "ok_up_to");
            for (std::size_t i = 0; i < params.size(); ++i) {
                const auto row = worst.row(static_cast<Eigen::Index>(i));
                if (!row.allFinite()) continue;  // no truth (alpha, beta of Scheibe eyes)
                std::printf("%-24s %-4s", params[i].name, unit_name(params[i].unit));
                if (std::isfinite(target[i])) {
                    std::printf(" %7.3g", target[i]);
                } else {
                    std::printf(" %7s", "-");
                }
                double ok_up_to = -1.0;
                bool ok = true;
                for (std::size_t j = 0; j < offsets.size(); ++j) {
                    const double e = row(static_cast<Eigen::Index>(j));
                    const bool miss = std::isfinite(target[i]) && e > target[i];
                    ok = ok && !miss;
                    if (ok) ok_up_to = offsets[j];
                    std::printf(" %7.3g%s", e, miss ? "*" : " ");
                }
                if (!std::isfinite(target[i])) {
                    std::printf(" %9s\n", "-");
                } else if (ok_up_to < 0.0) {
                    std::printf(" %9s\n", "never");
                } else {
                    std::printf(" %9.0f\n", ok_up_to);
                }
            }
            std::printf("%-24s %-4s %7s", "centre (error)", "um", "-");
            for (const double c : centre_err) std::printf(" %7.3g ", c);
            std::printf("\n%-24s %-4s %7.3g", "measured offset (max)", "um", 1e3 * limit_mm);
            for (const double c : measured) std::printf(" %7.3g ", c);
            std::printf("\n%-24s %-4s %7s", "flagged directions", "", "-");
            for (const int f : flagged) std::printf(" %5d/%-2d", f, dirs);
            std::printf("\n");
        }
    }
    std::printf("\n%d analyses, %.1f ms CPU per analysis; %d missing values\n", analyses,
                cpu_ms / analyses, failures);
    return failures == 0 ? 0 : 1;
}
