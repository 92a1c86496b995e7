#pragma once
// QC pictures of one CuBe analysis (`octshape macula --qc DIR`), each titled with the eye, scan
// pattern and size: the thickness map with colour bar (um), 1 mm scale bar, the centre, rim,
// slope and pit-flat disks (a line scan: thickness along the line); the radial profiles with
// their fitted Beziers on axes with values and units; the B-scan through the centre with the
// device ILM and BM and the fitted profile.

#include <opencv2/core.hpp>
#include <string>

#include "octshape/io/scan.h"
#include "octshape/retina/cube.h"

namespace octshape::qc {

// Writes DIR/STEM_thickness.png, DIR/STEM_profiles.png and DIR/STEM_bscan.png (atomically).
// `scan` is the analysed scan; its pixels are drawn when loaded. Throws OutputError.
void write_macula_qc(const retina::CubeResult& r, const io::Scan& scan, const std::string& dir,
                     const std::string& stem);

// Where the thickness picture of a radial scan draws a point of the radial frame (mm from the
// lines' crossing, x = SLO +x, y = superior): `ppm` pixels per mm, the crossing at `crossing`.
struct RadialThicknessLayout {
    double ppm = 1.0;
    cv::Point2d crossing{0.0, 0.0};
    [[nodiscard]] cv::Point px(double x_mm, double y_mm) const;
};

// A radial scan's thickness picture: the thickness along each line, drawn where the line was
// scanned (no value between the lines), with the disks, the centre and the crossing.
[[nodiscard]] cv::Mat macula_radial_thickness_picture(const retina::CubeResult& r,
                                                      const io::Scan& scan,
                                                      const std::string& title,
                                                      RadialThicknessLayout* layout = nullptr);

// The B-scan picture: a volume's B-scan through the centre, a radial scan's line nearest to
// the horizontal (nasal-temporal), with the fitted profile along the half-lines on it.
// `bscan` (when given) receives the B-scan's index.
[[nodiscard]] cv::Mat macula_bscan_picture(const retina::CubeResult& r,
                                           const io::Scan& scan,
                                           const std::string& title,
                                           int* bscan = nullptr);

// A volume's thickness map as its thickness picture draws it: `width_px` columns over the
// grid's extent in the fundus frame (fundus.h: superior up, as on the SLO, whichever way the
// B-scans ran), row 0 superior; each pixel the map's bilinear thickness (mm) at the pixel's
// fundus position, NaN where missing. CV_64FC1.
[[nodiscard]] cv::Mat fundus_thickness_raster(const retina::ThicknessMap& m,
                                              const io::Scan& scan,
                                              int width_px);

// The thickness colour range of the thickness pictures: [lo, hi] mm (VIRIDIS, lo dark).
[[nodiscard]] std::pair<double, double> macula_thickness_range(const retina::CubeResult& r);

}  // namespace octshape::qc
