#include "octshape/retina/scan_limits.h"

#include <cmath>
#include <sstream>
#include <string>

#include "octshape/error.h"

namespace octshape::retina {
namespace {

void check_range(double v, double lo, double hi, const char* what) {
    if (std::isfinite(v) && v >= lo && v <= hi) return;
    std::ostringstream s;
    s.precision(6);
    s << what << " " << v << " mm is not that of a Spectralis scan (expected " << lo << " to " << hi
      << " mm; docs/coordinates.md \"Plausible scans\")";
    throw AnalysisError(s.str());
}

}  // namespace

void check_scan_scales(const io::Scan& scan, bool needs_distance, const ScanLimits& limits) {
    const io::ScanMeta& m = scan.meta;
    check_range(m.scale_x_mm, limits.min_scale_x_mm, limits.max_scale_x_mm, "ScaleX (per A-scan)");
    check_range(m.scale_z_mm, limits.min_scale_z_mm, limits.max_scale_z_mm, "ScaleZ (per pixel)");
    if (needs_distance) {
        check_range(m.distance_mm, limits.min_distance_mm, limits.max_distance_mm,
                    "Distance (between B-scans)");
    }
}

}  // namespace octshape::retina
