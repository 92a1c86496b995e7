#include "octshape/retina/scan_geometry.h"

#include <algorithm>
#include <cmath>
#include <numbers>

#include <Eigen/LU>

namespace octshape::retina {
namespace {

// Positions stored in files are rounded; below this (mm) two positions are the same point.
constexpr double kPositionEps = 1e-6;

SpacingReport measure_spacing(const io::Scan& scan) {
    SpacingReport r;
    r.header_distance_mm = scan.meta.distance_mm;
    const int n = scan.num_bscans();
    r.num_gaps = std::max(0, n - 1);
    if (n < 2) return r;
    double sum = 0.0;
    r.min_mm = 1e300;
    r.max_mm = 0.0;
    for (int b = 1; b < n; ++b) {
        const auto& p = scan.bscans[static_cast<std::size_t>(b - 1)];
        const auto& q = scan.bscans[static_cast<std::size_t>(b)];
        const double gap = std::hypot(q.start_x_mm - p.start_x_mm, q.start_y_mm - p.start_y_mm);
        sum += gap;
        r.min_mm = std::min(r.min_mm, gap);
        r.max_mm = std::max(r.max_mm, gap);
    }
    r.mean_mm = sum / r.num_gaps;
    r.positions_known = r.mean_mm > kPositionEps;
    if (!r.positions_known) {
        r.min_mm = r.max_mm = r.mean_mm = 0.0;
        return r;
    }
    r.max_relative_deviation =
        std::max(r.max_mm - r.mean_mm, r.mean_mm - r.min_mm) / r.mean_mm;
    r.uniform = r.max_relative_deviation <= SpacingReport::kUniformTolerance;
    r.matches_header = r.header_distance_mm > 0.0 &&
                       std::fabs(r.mean_mm - r.header_distance_mm) <=
                           SpacingReport::kUniformTolerance * r.header_distance_mm;
    return r;
}

}  // namespace

ScanGeometry::ScanGeometry(const io::Scan& scan)
    : scale_x_mm_(scan.meta.scale_x_mm),
      scale_z_mm_(scan.meta.scale_z_mm),
      distance_mm_(scan.meta.distance_mm),
      spacing_(measure_spacing(scan)) {
    // Default placement when positions are unusable: A-scans left to right on the SLO, the
    // first B-scan most inferior (so grid +y is SLO -y).
    Eigen::Vector2d ex(1.0, 0.0);
    Eigen::Vector2d ey(0.0, -1.0);
    if (!scan.bscans.empty()) {
        const io::BScan& first = scan.bscans.front();
        origin_slo_ = {first.start_x_mm, first.start_y_mm};
        const Eigen::Vector2d along(first.end_x_mm - first.start_x_mm,
                                    first.end_y_mm - first.start_y_mm);
        const bool line_like = scan.meta.pattern != io::ScanPattern::kCircle &&
                               scan.meta.pattern != io::ScanPattern::kRadialCircles;
        if (line_like && along.norm() > kPositionEps) {
            ex = along.normalized();
            from_positions_ = true;
            const io::BScan& last = scan.bscans.back();
            const Eigen::Vector2d across(last.start_x_mm - first.start_x_mm,
                                         last.start_y_mm - first.start_y_mm);
            // Across-scan direction: from the positions when they spread, else perpendicular to
            // the B-scan, turned so that a horizontal B-scan's +y is superior (SLO -y).
            if (across.norm() > kPositionEps) {
                ey = across.normalized();
            } else {
                ey = Eigen::Vector2d(ex.y(), -ex.x());
                // Several B-scans at one position: which way the volume runs is assumed, so
                // the orientation does not come from the positions.
                if (scan.num_bscans() > 1) from_positions_ = false;
            }
        }
    }
    to_slo_.col(0) = ex;
    to_slo_.col(1) = ey;
    const double nasal_sign = scan.meta.laterality == io::Laterality::kOS ? -1.0 : 1.0;
    // Anatomical (nasal, superior) from SLO offsets (dx, dy): nasal = sign*dx, superior = -dy.
    Eigen::Matrix2d slo_to_anat;
    slo_to_anat << nasal_sign, 0.0, 0.0, -1.0;
    to_anat_ = slo_to_anat * to_slo_;
}

double ScanGeometry::anatomical_angle_deg(double dx, double dy) const {
    const Eigen::Vector2d a = to_anat_ * Eigen::Vector2d(dx, dy);
    double deg = std::atan2(a.y(), a.x()) * 180.0 / std::numbers::pi;
    if (deg < 0.0) deg += 360.0;
    if (deg >= 360.0) deg -= 360.0;
    return deg;
}

Eigen::Vector2d ScanGeometry::grid_to_slo(const Eigen::Vector2d& grid_mm) const {
    return origin_slo_ + to_slo_ * grid_mm;
}

Eigen::Vector2d ScanGeometry::slo_to_grid(const Eigen::Vector2d& slo_mm) const {
    return to_slo_.inverse() * (slo_mm - origin_slo_);
}

}  // namespace octshape::retina
