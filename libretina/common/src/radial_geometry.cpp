#include "octshape/retina/radial_geometry.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <numeric>
#include <sstream>

#include <Eigen/Dense>

#include "octshape/error.h"

namespace octshape::retina {
namespace {

constexpr double kDeg = 180.0 / std::numbers::pi;
// Positions stored in files are rounded; below this (mm) two positions are the same point.
constexpr double kPositionEps = 1e-6;

double wrap360(double deg) {
    deg = std::fmod(deg, 360.0);
    if (deg < 0.0) deg += 360.0;
    if (deg >= 360.0) deg -= 360.0;
    return deg;
}

Eigen::Vector2d slo_direction(const io::BScan& b) {
    return {b.end_x_mm - b.start_x_mm, b.end_y_mm - b.start_y_mm};
}

}  // namespace

bool is_radial_scan(const io::Scan& scan) {
    if (scan.meta.pattern == io::ScanPattern::kRadial) return true;
    if (scan.meta.pattern != io::ScanPattern::kUnknown || scan.num_bscans() < 2) return false;
    const Eigen::Vector2d d0 = slo_direction(scan.bscans.front());
    if (d0.norm() <= kPositionEps) return false;
    for (const io::BScan& b : scan.bscans) {
        const Eigen::Vector2d d = slo_direction(b);
        if (d.norm() <= kPositionEps) return false;
        const double sin_angle = std::fabs(d0.x() * d.y() - d0.y() * d.x()) / (d0.norm() * d.norm());
        if (sin_angle > std::sin(1.0 / kDeg)) return true;
    }
    return false;
}

Eigen::Vector2d RadialGeometry::direction(int line) const {
    const RadialLine& l = lines[static_cast<std::size_t>(line)];
    const Eigen::Vector2d d = l.end_slo_mm - l.start_slo_mm;
    return Eigen::Vector2d(d.x(), -d.y()).normalized();
}

Eigen::Vector2d RadialGeometry::ascan_mm(int line, double ascan, int size_x) const {
    const RadialLine& l = lines[static_cast<std::size_t>(line)];
    const double f = size_x > 1 ? ascan / (size_x - 1) : 0.0;
    return slo_to_radial(l.start_slo_mm + f * (l.end_slo_mm - l.start_slo_mm));
}

double RadialGeometry::anatomical_angle_deg(const Eigen::Vector2d& d) const {
    const Eigen::Vector2d a = radial_to_anatomical * d;
    return wrap360(std::atan2(a.y(), a.x()) * kDeg);
}

RadialGeometry radial_geometry(const io::Scan& scan) {
    const int n = scan.num_bscans();
    if (n < 2) {
        throw AnalysisError("radial scan with " + std::to_string(n) +
                            " B-scan(s): at least 2 lines are needed for a crossing");
    }
    RadialGeometry g;
    const double nasal_sign = scan.meta.laterality == io::Laterality::kOS ? -1.0 : 1.0;
    g.radial_to_anatomical << nasal_sign, 0.0, 0.0, 1.0;
    g.header_length_mm = std::max(0, scan.meta.size_x - 1) * scan.meta.scale_x_mm;
    // Least-squares crossing: minimise sum_k |(I - u_k u_k^T)(c - p_k)|^2, i.e.
    // (sum_k P_k) c = sum_k P_k p_k with P_k the projector across line k.
    Eigen::Matrix2d a = Eigen::Matrix2d::Zero();
    Eigen::Vector2d rhs = Eigen::Vector2d::Zero();
    double length_sum = 0.0;
    for (int k = 0; k < n; ++k) {
        const io::BScan& b = scan.bscans[static_cast<std::size_t>(k)];
        RadialLine l;
        l.bscan = k;
        l.start_slo_mm = {b.start_x_mm, b.start_y_mm};
        l.end_slo_mm = {b.end_x_mm, b.end_y_mm};
        if (!l.start_slo_mm.allFinite() || !l.end_slo_mm.allFinite()) {
            throw AnalysisError("radial scan: B-scan " + std::to_string(k) +
                                " has a position on the SLO that is not a number");
        }
        l.length_mm = (l.end_slo_mm - l.start_slo_mm).norm();
        if (!(l.length_mm > kPositionEps) || !std::isfinite(l.length_mm)) {
            throw AnalysisError("radial scan: B-scan " + std::to_string(k) +
                                " has Start = End on the SLO: its line is unknown");
        }
        const Eigen::Vector2d u = (l.end_slo_mm - l.start_slo_mm) / l.length_mm;
        const Eigen::Matrix2d p = Eigen::Matrix2d::Identity() - u * u.transpose();
        a += p;
        rhs += p * l.start_slo_mm;
        length_sum += l.length_mm;
        g.lines.push_back(l);
    }
    // Both eigenvalues of sum P_k are n/2 for evenly spread lines, 0 (smallest) when all are
    // parallel; below 1e-6 n no crossing is determined.
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> es(a);
    if (!(es.eigenvalues()(0) > 1e-6 * n)) {
        throw AnalysisError("radial scan whose " + std::to_string(n) +
                            " B-scans are parallel on the SLO: the lines do not cross");
    }
    g.crossing_slo_mm = a.ldlt().solve(rhs);
    g.mean_length_mm = length_sum / n;
    double sq = 0.0;
    for (int k = 0; k < n; ++k) {
        RadialLine& l = g.lines[static_cast<std::size_t>(k)];
        const Eigen::Vector2d u = (l.end_slo_mm - l.start_slo_mm) / l.length_mm;
        const Eigen::Vector2d w = g.crossing_slo_mm - l.start_slo_mm;
        l.crossing_along_mm = w.dot(u);
        l.miss_mm = std::fabs(w.x() * u.y() - w.y() * u.x());
        g.max_miss_mm = std::max(g.max_miss_mm, l.miss_mm);
        sq += l.miss_mm * l.miss_mm;
        l.angle_deg = g.anatomical_angle_deg(g.direction(k));
        l.line_angle_deg = std::fmod(l.angle_deg, 180.0);
    }
    g.rms_miss_mm = std::sqrt(sq / n);
    g.lines_cross =
        g.max_miss_mm <= RadialGeometry::kMissTolerance * std::max(scan.meta.scale_x_mm, 1e-3);

    // Angular steps between neighbouring orientations, cyclic over 180 deg.
    std::vector<int> order(static_cast<std::size_t>(n));
    std::iota(order.begin(), order.end(), 0);
    std::sort(order.begin(), order.end(), [&](int i, int j) {
        return g.lines[static_cast<std::size_t>(i)].line_angle_deg <
               g.lines[static_cast<std::size_t>(j)].line_angle_deg;
    });
    g.nominal_step_deg = 180.0 / n;
    g.min_step_deg = 1e300;
    g.max_step_deg = 0.0;
    for (int i = 0; i < n; ++i) {
        const RadialLine& p = g.lines[static_cast<std::size_t>(order[static_cast<std::size_t>(i)])];
        const RadialLine& q =
            g.lines[static_cast<std::size_t>(order[static_cast<std::size_t>((i + 1) % n)])];
        double step = q.line_angle_deg - p.line_angle_deg;
        if (i == n - 1) step += 180.0;
        g.min_step_deg = std::min(g.min_step_deg, step);
        g.max_step_deg = std::max(g.max_step_deg, step);
        if (std::fabs(step - g.nominal_step_deg) >
            RadialGeometry::kStepTolerance * g.nominal_step_deg) {
            g.regular = false;
            std::ostringstream s;
            s.setf(std::ios::fixed);
            s.precision(2);
            s << "B-scans " << p.bscan << " (" << p.line_angle_deg << " deg) and " << q.bscan
              << " (" << q.line_angle_deg << " deg): step " << step << " deg";
            g.irregular_steps.push_back(s.str());
        }
    }
    for (const io::BScan& b : scan.bscans) {
        if (b.bmo) ++g.num_bmo_fields;
    }
    return g;
}

RadialGeometryQc radial_geometry_qc(const RadialGeometry& g) {
    RadialGeometryQc qc;
    const auto fixed = [](double v, int digits) {
        std::ostringstream s;
        s.setf(std::ios::fixed);
        s.precision(digits);
        s << v;
        return s.str();
    };
    if (!g.regular) {
        qc.flags.emplace_back("radial angular steps irregular");
        qc.notes.push_back("radial angular steps from " + fixed(g.min_step_deg, 2) + " to " +
                           fixed(g.max_step_deg, 2) + " deg (nominal " +
                           fixed(g.nominal_step_deg, 2) + ")");
        for (const std::string& s : g.irregular_steps) qc.notes.push_back("irregular step: " + s);
    }
    if (!g.lines_cross) {
        qc.flags.emplace_back("radial lines miss their crossing");
        qc.notes.push_back("radial lines miss their common crossing by up to " +
                           fixed(1e3 * g.max_miss_mm, 1) + " um (RMS " +
                           fixed(1e3 * g.rms_miss_mm, 1) + " um)");
    }
    if (g.num_bmo_fields > 0) {
        qc.notes.push_back("HSF-OCT-104 BMO fields present in " +
                           std::to_string(g.num_bmo_fields) +
                           " B-scans: not used (their meaning is unverified)");
    }
    return qc;
}

}  // namespace octshape::retina
