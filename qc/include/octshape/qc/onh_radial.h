#pragma once
// The QC pictures of a radial ONH scan (ScanPattern 5; docs/outputs.md "QC pictures"): the
// en-face picture of the scanned circle with the lines where they were scanned, and a contact
// sheet of every radial B-scan. The MRW picture is the volume's (onh.cpp) with the in-plane
// MRW added. Each picture comes with its layout (where a grid mm point, or a B-scan pixel, is
// drawn) so that the tests can check marks at their pixels.

#include <cmath>
#include <functional>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "octshape/io/scan.h"
#include "octshape/qc/draw.h"
#include "octshape/retina/onh.h"
#include "octshape/retina/radial_geometry.h"

namespace octshape::qc {

// The colours of what an ONH picture draws, the same in a volume's and a radial scan's.
namespace onh_colours {
inline const cv::Scalar& kEllipse = palette::kRed;
inline const cv::Scalar& kDisc = palette::kYellow;
inline const cv::Scalar& kBmo = palette::kWhite;
inline const cv::Scalar& kDeviceIlm = palette::kGreen;
inline const cv::Scalar& kUsedIlm = palette::kRed;  // was (40, 40, 240): the one red of the palette
inline const cv::Scalar& kBm = palette::kBlue;
inline const cv::Scalar& kMrw = palette::kPink;
}  // namespace onh_colours

// ", moved 12 um up" when the axial registration moved B-scan `b`, ", moved 9 um left" (towards
// lower A-scans) when the lateral one did, both joined ", moved 12 um up, 9 um left"; nothing
// below 0.5 um: the B-scan titles of both patterns' pictures show what the registration did.
inline std::string registration_title(const retina::OnhResult& r, int b) {
    const auto moved = [b](bool applied, const std::vector<double>& s) {
        if (!applied || b < 0 || static_cast<std::size_t>(b) >= s.size()) return 0.0;
        return s[static_cast<std::size_t>(b)];
    };
    return registration_title(moved(r.axial_registration.applied, r.axial_registration.shift_um),
                              moved(r.lateral_registration.applied, r.lateral_registration.shift_um));
}

// En-face picture: the (n - 1) x (n - 1) cells of the radial grid, `ppm` pixels per mm, inside
// a margin (for the lines' labels) under the title strip.
struct RadialEnfaceLayout {
    double ppm = 1.0;    // picture pixels per mm
    int margin = 0;      // pixels around the grid
    int map_height = 0;  // pixels of the grid's height
    int top = 0;         // rows above the canvas (title strip)
    // Picture pixel of grid mm (x, y); y up (superior at the top).
    [[nodiscard]] cv::Point px(double x_mm, double y_mm) const;
};

// Contact sheet: B-scan k in panel (k % cols, k / cols), each panel_w x panel_h pixels of the
// B-scan's depth rows [z0, z1) (all A-scans), `gap` pixels between panels, below `top` rows.
struct RadialSheetLayout {
    int lines = 0;
    int cols = 1;
    int rows = 1;
    int size_x = 0;
    int z0 = 0;  // first depth row shown
    int z1 = 0;  // one past the last
    int panel_w = 0;
    int panel_h = 0;
    int gap = 0;
    int top = 0;
    [[nodiscard]] double sx() const { return static_cast<double>(panel_w) / size_x; }
    [[nodiscard]] double sz() const { return static_cast<double>(panel_h) / (z1 - z0); }
    // Top-left pixel of panel `line`.
    [[nodiscard]] cv::Point origin(int line) const;
    // Picture pixel of A-scan `ascan` and depth `depth_px` (pixel indices, values at pixel
    // centres, fractional) of B-scan `line`.
    [[nodiscard]] cv::Point px(int line, double ascan, double depth_px) const;
};

// The analysis's en-face map (retina::onh_enface_heights: height above the RPE of the topmost
// ILM face over each RPE grid cell, NaN: no face) as the en-face pictures draw it, a volume's
// and a radial scan's: three 8-bit layers of `size` cells, cell (a, b) of the grid at the
// picture cell place(a, b) — `grey`, the height's colour level (0 at lo, 255 at hi; 0 where no
// face), `cup`, 255 where the height is below the RPE (the cup's outline is its boundary), and
// `none`, 255 where no face lies — with the colour range [lo, hi] (lo <= 0, hi >= 0.1 mm, so
// that a flat disc is not stretched over the whole scale) and the grid's cells (cols x rows).
struct CellLayers {
    cv::Mat grey;
    cv::Mat cup;
    cv::Mat none;
    double lo = 0.0;
    double hi = 0.1;
    int cols = 0;
    int rows = 0;
};
// `size` is the picture's cells (width x height); `place` maps grid cell (a, b) into it. With an
// empty `size`, the grid's own (cols x rows) and place(a, b) = (a, rows - 1 - b): superior up.
[[nodiscard]] CellLayers onh_cell_layers(const retina::OnhResult& r,
                                         cv::Size size = {},
                                         const std::function<cv::Point(int, int)>& place = {});

// Fractional A-scan index along line `line` of grid mm point `xy` (its projection on the line).
[[nodiscard]] double radial_ascan_of(const retina::RadialGeometry& geo,
                                     const retina::OnhResult& r,
                                     int line,
                                     int size_x,
                                     const Eigen::Vector2d& xy);

[[nodiscard]] cv::Mat radial_enface_picture(const io::Scan& scan,
                                            const retina::OnhResult& r,
                                            const retina::OnhParams& p,
                                            const std::string& title,
                                            RadialEnfaceLayout* layout = nullptr);

[[nodiscard]] cv::Mat radial_bscans_picture(const io::Scan& scan,
                                            const retina::OnhResult& r,
                                            const std::string& title,
                                            RadialSheetLayout* layout = nullptr);

// The MRW per BMO point against the anatomical angle: 3-D (every resampled ellipse point) and,
// for a radial scan, in-plane (every measured BMO point, numbered by its B-scan).
[[nodiscard]] cv::Mat onh_mrw_picture(const retina::OnhResult& r, const std::string& title);

}  // namespace octshape::qc
