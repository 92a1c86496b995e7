#pragma once
// The fundus frame of the en-face pictures (docs/outputs.md "QC pictures"): x to the right and
// y up as on the fundus (SLO) image, so that superior is up and nasal is to the right for a
// right eye, to the left for a left eye, whatever the direction of the B-scans. A radial scan's
// frame is this frame already (retina/radial_geometry.h); a grid (volume, line) is placed by
// its B-scans' positions on the SLO (retina::ScanGeometry), turned to the nearest quarter turn
// (grids are axis-aligned on the SLO), so that its nodes stay on the pixel grid of the picture.

#include <array>

#include <Eigen/Core>

#include "octshape/io/scan.h"

namespace octshape::qc {

struct FundusFrame {
    // fundus x = sx * grid[ix] + origin.x, fundus y = sy * grid[iy] + origin.y: a signed
    // permutation of the grid axes (ix != iy, signs +-1). A horizontal volume whose first
    // B-scan is the most inferior (the usual Spectralis placement) has the identity here.
    int ix = 0;
    int iy = 1;
    double sx = 1.0;
    double sy = 1.0;
    Eigen::Vector2d origin = Eigen::Vector2d::Zero();
    // The grid's rectangle [0, W] x [0, H] (grid mm) becomes [0, width] x [0, height] here.
    double width_mm = 0.0;
    double height_mm = 0.0;

    [[nodiscard]] Eigen::Vector2d to_fundus(const Eigen::Vector2d& grid_mm) const {
        return {sx * grid_mm[ix] + origin.x(), sy * grid_mm[iy] + origin.y()};
    }
    [[nodiscard]] Eigen::Vector2d to_grid(const Eigen::Vector2d& fundus_mm) const {
        Eigen::Vector2d g;
        g[ix] = sx * (fundus_mm.x() - origin.x());
        g[iy] = sy * (fundus_mm.y() - origin.y());
        return g;
    }
    // True when grid x runs along fundus x (horizontal B-scans).
    [[nodiscard]] bool keeps_axes() const { return ix == 0; }
    // Cell (a, b) of a grid of cols x rows cells filling the frame (cell (a, b) spans
    // [a, a + 1) x [b, b + 1) grid steps) as the (column, row from the bottom) of the same cells
    // seen in this frame, which has cols x rows of them when keeps_axes(), else rows x cols.
    [[nodiscard]] std::array<int, 2> fundus_cell(int a, int b, int cols, int rows) const {
        const int i[2] = {a, b};
        const int n[2] = {cols, rows};
        return {sx > 0.0 ? i[ix] : n[ix] - 1 - i[ix], sy > 0.0 ? i[iy] : n[iy] - 1 - i[iy]};
    }
};

// The frame of `scan`'s grid of grid_width_mm x grid_height_mm (grid x along the B-scans).
[[nodiscard]] FundusFrame fundus_frame(const io::Scan& scan,
                                       double grid_width_mm,
                                       double grid_height_mm);

}  // namespace octshape::qc
