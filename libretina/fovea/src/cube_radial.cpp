// CuBe on a radial scan (ScanPattern 5): the stages of cube_stages.h's "radial path". Each
// B-scan gives two half-lines along its own line; the fits run on the measured A-scans.
// Decisions and measurements: docs/algorithms/cube.md "Radial scans".

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <sstream>

#include "cube_stages.h"
#include "octshape/error.h"
#include "octshape/retina/cube.h"
#include "octshape/retina/scan_limits.h"

namespace octshape::retina::cube_detail {
namespace {

// The crossing offset beyond which the centre is flagged (QC "centre off the line crossing"),
// read from the crossing-offset table (bench/macula_radial: 12 and 24 lines, Bezier and
// Scheibe eyes, worst of 8 directions; tests/retina/cube_radial_test.cpp asserts it on 3;
// docs/algorithms/cube.md "Radial scans"): the largest offset tabulated at which every
// parameter meets the volume analysis's targets (1 %, 2 um, 0.2 deg) is 25 um; at 50 um the
// Bezier pit-flat diameter (2.7 um) and slope diameter (8.1 um) miss them, at 75 um also the
// pit volume (1.1 %).
constexpr double kRadialOffsetLimitMm = 0.025;

// Samples closer than this (mm) to the centre are the centre itself.
constexpr double kSameRadiusMm = 1e-9;

struct LineSamples {
    std::vector<V2> pos;     // radial frame, mm
    std::vector<double> mm;  // thickness, NaN = missing
};

std::vector<LineSamples> line_samples(const ThicknessMap& m, const RadialGeometry& g, int size_x) {
    std::vector<LineSamples> out(g.lines.size());
    for (int k = 0; k < static_cast<int>(g.lines.size()); ++k) {
        LineSamples& l = out[static_cast<std::size_t>(k)];
        for (int a = 0; a < m.cols; ++a) {
            l.pos.push_back(g.ascan_mm(k, a, size_x));
            l.mm.push_back(m.at(k, a));
        }
    }
    return out;
}

// Gaussian smoothing of one line's samples along the line (SD sd_mm, missing values skipped);
// sd 0: the samples themselves.
std::vector<double> smooth_along(const std::vector<double>& v, double step_mm, double sd_mm) {
    if (!(sd_mm > 0.0)) return v;
    const int half = std::max(1, static_cast<int>(std::ceil(3.0 * sd_mm / step_mm)));
    std::vector<double> out(v.size(), kMissing);
    const int n = static_cast<int>(v.size());
    for (int i = 0; i < n; ++i) {
        if (std::isnan(v[static_cast<std::size_t>(i)])) continue;
        double sw = 0.0;
        double s = 0.0;
        for (int j = std::max(0, i - half); j <= std::min(n - 1, i + half); ++j) {
            const double x = v[static_cast<std::size_t>(j)];
            if (std::isnan(x)) continue;
            const double d = (j - i) * step_mm / sd_mm;
            const double w = std::exp(-0.5 * d * d);
            sw += w;
            s += w * x;
        }
        out[static_cast<std::size_t>(i)] = s / sw;
    }
    return out;
}

// Least-squares quadratic surface z = c0 + c1 x + c2 y + c3 x^2 + c4 xy + c5 y^2 (about `at`)
// over the valid samples within `radius` of `at`; its vertex when it is a minimum within the
// window. False when the window's samples do not determine one.
bool quadratic_vertex(const std::vector<LineSamples>& lines,
                      const V2& at,
                      double radius,
                      V2& vertex,
                      double& height) {
    Eigen::Matrix<double, 6, 6> ata = Eigen::Matrix<double, 6, 6>::Zero();
    Eigen::Matrix<double, 6, 1> atb = Eigen::Matrix<double, 6, 1>::Zero();
    int count = 0;
    for (const LineSamples& l : lines) {
        for (std::size_t i = 0; i < l.pos.size(); ++i) {
            if (std::isnan(l.mm[i])) continue;
            const V2 d = l.pos[i] - at;
            if (d.norm() > radius) continue;
            Eigen::Matrix<double, 6, 1> row;
            row << 1.0, d.x(), d.y(), d.x() * d.x(), d.x() * d.y(), d.y() * d.y();
            ata += row * row.transpose();
            atb += row * l.mm[i];
            ++count;
        }
    }
    if (count < 12) return false;
    const Eigen::FullPivLU<Eigen::Matrix<double, 6, 6>> lu(ata);
    if (lu.rank() < 6) return false;
    const Eigen::Matrix<double, 6, 1> c = lu.solve(atb);
    Eigen::Matrix2d h;
    h << 2.0 * c(3), c(4), c(4), 2.0 * c(5);
    if (!(h.determinant() > 0.0 && h(0, 0) > 0.0)) return false;  // not a minimum
    const V2 v = h.ldlt().solve(-V2(c(1), c(2)));
    if (!(v.norm() <= radius)) return false;
    vertex = at + v;
    height = c(0) + c(1) * v.x() + c(2) * v.y() + c(3) * v.x() * v.x() + c(4) * v.x() * v.y() +
             c(5) * v.y() * v.y();
    return std::isfinite(height);
}

}  // namespace

RadialGeometry radial_check(const io::Scan& scan, const CubeParams& params) {
    if (!(scan.meta.scale_x_mm > 0.0) || !(scan.meta.scale_z_mm > 0.0)) {
        throw AnalysisError("the scan's ScaleX/ScaleZ are not positive");
    }
    check_scan_scales(scan, false);
    RadialGeometry g = radial_geometry(scan);
    if (g.mean_length_mm < 2.0 * params.radius_mm) {
        std::ostringstream s;
        s.precision(4);
        s << "the radial lines (" << g.mean_length_mm
          << " mm) are shorter than two half-lines of " << params.radius_mm
          << " mm: no half-line can reach the rim (a smaller --radius-mm, or longer lines)";
        throw AnalysisError(s.str());
    }
    return g;
}

Centre radial_centre(const RadialCentreInput& in) {
    Centre out;
    out.search_centre_mm = V2::Zero();  // the crossing
    const std::vector<LineSamples> lines = line_samples(in.map, in.geo, in.size_x);
    if (in.params.centre_mm) {
        out.source = "given";
        out.centre_mm = *in.params.centre_mm;
    } else {
        out.source = "thickness minimum near the line crossing";
        // The minimum of the along-line smoothed thickness within the search radius of the
        // crossing (the smoothing keeps segmentation noise from picking a low outlier).
        double best = std::numeric_limits<double>::infinity();
        for (std::size_t k = 0; k < lines.size(); ++k) {
            const double step = in.geo.lines[k].length_mm / std::max(1, in.size_x - 1);
            const std::vector<double> sm =
                smooth_along(lines[k].mm, step, in.params.centre_smoothing_mm);
            for (std::size_t i = 0; i < sm.size(); ++i) {
                if (std::isnan(sm[i]) || lines[k].pos[i].norm() > in.params.search_radius_mm) {
                    continue;
                }
                if (sm[i] < best) {
                    best = sm[i];
                    out.centre_mm = lines[k].pos[i];
                }
            }
        }
        if (!std::isfinite(best)) {
            throw AnalysisError("no valid thickness within the search radius of the line crossing");
        }
        // Refinement: the vertex of a quadratic surface over a window that every line crosses
        // (the lines pass the minimum at most its distance from the crossing away), re-centred
        // on the vertex twice.
        const double w0 = std::max(in.params.centre_fit_radius_mm, 0.02);
        for (int round = 0; round < 3 && in.params.centre_fit_radius_mm > 0.0; ++round) {
            const double w = w0 + out.centre_mm.norm();
            V2 v;
            double hgt = 0.0;
            if (!quadratic_vertex(lines, out.centre_mm, w, v, hgt)) break;
            out.centre_mm = v;
            out.sample_mm = hgt;
            out.fit_radius_mm = w;
        }
        if ((out.centre_mm).norm() > in.params.search_radius_mm - in.map.dx_mm) {
            out.qc_flags.push_back("centre at search border");
        }
    }
    // CFT sample: the surface's height at the centre, else the nearest valid sample.
    double nearest = std::numeric_limits<double>::infinity();
    for (const LineSamples& l : lines) {
        for (std::size_t i = 0; i < l.pos.size(); ++i) {
            const double d = (l.pos[i] - out.centre_mm).norm();
            if (!std::isnan(l.mm[i]) && d < nearest) {
                nearest = d;
                out.cft_mm = l.mm[i];
            }
        }
    }
    if (std::isnan(out.cft_mm)) throw AnalysisError("no valid thickness at the centre found");
    if (!std::isnan(out.sample_mm)) out.cft_mm = out.sample_mm;
    return out;
}

RadialSamples radial_half_lines(const ThicknessMap& m,
                                const RadialGeometry& geo,
                                const CubeParams& params,
                                const V2& centre_mm,
                                double cft_mm,
                                int size_x) {
    RadialSamples out;
    const double r_max = params.radius_mm + kSameRadiusMm;
    std::vector<CubeHalfLine> lines;
    double step_sum = 0.0;
    for (int k = 0; k < static_cast<int>(geo.lines.size()); ++k) {
        const double step = geo.lines[static_cast<std::size_t>(k)].length_mm / (size_x - 1);
        step_sum += step;
        const V2 u = geo.direction(k);
        const V2 p0 = geo.ascan_mm(k, 0, size_x);
        const double s0 = (centre_mm - p0).dot(u);  // the foot of the centre, mm from Start
        const V2 foot = p0 + s0 * u;
        // The line passes the centre at distance `miss`: the A-scan s mm from the foot lies at
        // rho = sqrt(s^2 + miss^2) from the centre, so the half-line is fitted as a radial
        // profile about the centre (docs/algorithms/cube.md "Radial scans", step 4).
        const double miss = (centre_mm - foot).norm();
        const double s_max = std::sqrt(std::max(0.0, r_max * r_max - miss * miss));
        for (const double sign : {1.0, -1.0}) {
            CubeHalfLine h;
            h.direction = sign * u;
            h.angle_deg = geo.anatomical_angle_deg(h.direction);
            h.foot_mm = foot;  // origin_mm stays NaN: r = 0 is the centre
            h.r_mm.push_back(0.0);
            h.h_mm.push_back(cft_mm);
            // A-scans beyond the foot in this direction, nearest first (one at the foot itself
            // belongs to the + side).
            const int a_first = sign > 0 ? static_cast<int>(std::ceil(s0 / step))
                                         : static_cast<int>(std::ceil(s0 / step)) - 1;
            for (int a = a_first; a >= 0 && a < m.cols; a += sign > 0 ? 1 : -1) {
                const double s = sign * (a * step - s0);
                if (s < 0.0) continue;
                if (s > s_max) break;
                const double rho = std::hypot(s, miss);
                if (rho <= kSameRadiusMm) continue;  // the centre itself
                h.r_mm.push_back(rho);
                h.h_mm.push_back(m.at(k, a));
                if (std::isnan(h.h_mm.back())) ++h.num_missing;
            }
            if (h.r_mm.back() < params.radius_mm - 1.5 * step) {
                // The B-scan ends before R on this side: no exterior to fit to R.
                h.r_mm.resize(1);
                h.h_mm.resize(1);
            }
            lines.push_back(std::move(h));
        }
    }
    // Angular order: the lines' orientations lie in [0, 180) and their opposites in
    // [180, 360), so half-line i + n/2 is opposite half-line i (Eq. 7.18 pairs them).
    std::stable_sort(lines.begin(), lines.end(), [](const CubeHalfLine& a, const CubeHalfLine& b) {
        return a.angle_deg < b.angle_deg;
    });
    out.half_lines = std::move(lines);
    out.spacing_mm = step_sum / static_cast<double>(geo.lines.size());
    return out;
}

double radial_offset_limit_mm() {
    // From the crossing-offset table (bench/macula_radial, docs/algorithms/cube.md "Radial
    // scans"): see there for the measurement this limit is read from.
    return kRadialOffsetLimitMm;
}

void radial_qc(CubeResult& res,
               const io::Scan& scan,
               const RadialGeometry& geo,
               const CubeParams& params) {
    macula_qc(res, scan, ScanGeometry(scan), params);
    const RadialGeometryQc qc = radial_geometry_qc(geo);
    res.qc_flags.insert(res.qc_flags.end(), qc.flags.begin(), qc.flags.end());
    res.notes.insert(res.notes.end(), qc.notes.begin(), qc.notes.end());
    if (!geo.regular) {
        res.notes.push_back("volumes weight every half-line by 2 pi / n although the steps differ");
    }
    if (res.radial.centre_offset_distance_mm > res.radial.centre_offset_limit_mm) {
        res.qc_flags.push_back("centre off the line crossing");
    }
}

CubeResult analyse_macula_radial(const io::Scan& scan, const CubeParams& params) {
    const RadialGeometry geo = radial_check(scan, params);
    CubeResult res;
    res.radial_scan = true;
    res.map = thickness_map(scan);
    const double noise_sd_mm = thickness_noise_sd(res.map);
    res.thickness_noise_sd_um = noise_sd_mm * 1e3;
    const double crest_mm = 3.0 * noise_sd_mm;  // as for a volume (cube.cpp)

    Centre centre = radial_centre(
        {.map = res.map, .geo = geo, .params = params, .size_x = scan.meta.size_x});
    const double centre_sample_mm = centre.sample_mm;
    take_centre(res, std::move(centre));

    RadialSamples samples = radial_half_lines(res.map, geo, params, res.centre_mm, res.cft_mm,
                                              scan.meta.size_x);
    res.sample_spacing_mm = samples.spacing_mm;
    fit_half_lines(res, samples, centre_sample_mm, params, crest_mm);

    CubeRadial& r = res.radial;
    r.num_lines = static_cast<int>(geo.lines.size());
    r.line_length_mm = geo.mean_length_mm;
    r.angular_step_deg = geo.nominal_step_deg;
    r.regular = geo.regular;
    r.max_miss_mm = geo.max_miss_mm;
    r.centre_offset_mm = res.centre_mm;
    r.centre_offset_distance_mm = res.centre_mm.norm();
    r.centre_offset_limit_mm = radial_offset_limit_mm();
    r.num_bmo_fields = geo.num_bmo_fields;

    summarise_macula(res, params);
    radial_qc(res, scan, geo, params);
    check_macula_result(res, scan);
    return res;
}

}  // namespace octshape::retina::cube_detail
