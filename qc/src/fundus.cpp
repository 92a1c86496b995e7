#include "octshape/qc/fundus.h"

#include <cmath>

#include "octshape/retina/scan_geometry.h"

namespace octshape::qc {

FundusFrame fundus_frame(const io::Scan& scan, double grid_width_mm, double grid_height_mm) {
    const retina::ScanGeometry geo(scan);
    const Eigen::Vector2d o = geo.grid_to_slo({0.0, 0.0});
    // Where grid +x and +y point on the fundus image: SLO offsets with y turned up.
    auto fundus_dir = [&](const Eigen::Vector2d& g) {
        const Eigen::Vector2d d = geo.grid_to_slo(g) - o;
        return Eigen::Vector2d(d.x(), -d.y());
    };
    const Eigen::Vector2d ex = fundus_dir({1.0, 0.0});
    const Eigen::Vector2d ey = fundus_dir({0.0, 1.0});
    FundusFrame f;
    // Grid x on the fundus axis it is nearest to; grid y on the other one.
    const bool x_horizontal = std::fabs(ex.x()) >= std::fabs(ex.y());
    const double x_sign = (x_horizontal ? ex.x() : ex.y()) < 0.0 ? -1.0 : 1.0;
    const double y_sign = (x_horizontal ? ey.y() : ey.x()) < 0.0 ? -1.0 : 1.0;
    if (x_horizontal) {
        f.ix = 0;
        f.iy = 1;
        f.sx = x_sign;
        f.sy = y_sign;
        f.width_mm = grid_width_mm;
        f.height_mm = grid_height_mm;
    } else {
        f.ix = 1;
        f.iy = 0;
        f.sx = y_sign;
        f.sy = x_sign;
        f.width_mm = grid_height_mm;
        f.height_mm = grid_width_mm;
    }
    // A reversed axis starts at the far edge of the grid.
    f.origin = {f.sx < 0.0 ? f.width_mm : 0.0, f.sy < 0.0 ? f.height_mm : 0.0};
    return f;
}

}  // namespace octshape::qc
