#include "octshape/qc/macula.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <optional>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <vector>

#include "octshape/qc/draw.h"
#include "octshape/qc/fundus.h"
#include "octshape/qc/names.h"
#include "octshape/error.h"
#include "octshape/retina/radial_geometry.h"

namespace octshape::qc {
namespace {

const cv::Scalar& kRim = palette::kRed;
const cv::Scalar& kSlope = palette::kAmber;
const cv::Scalar& kFlat = palette::kWhite;
const cv::Scalar& kInterior = palette::kDarkGreen;
const cv::Scalar& kExterior = palette::kDeepBlue;
const cv::Scalar& kCentre = palette::kMagenta;
const cv::Scalar& kIlm = palette::kGreen;
const cv::Scalar& kBm = palette::kBlue;
const cv::Scalar& kFit = palette::kYellow;
const cv::Scalar& kText = palette::kText;
const cv::Scalar& kPanel = palette::kPanel;

// A dark strip of `h` pixels with the title on it.
cv::Mat title_strip(int w, int h, const std::string& title) {
    cv::Mat s(h, w, CV_8UC3, kPanel);
    outlined_text(s, title, {8, h - 10}, 0.55, palette::kWhite);
    return s;
}

cv::Mat stack(const std::vector<cv::Mat>& parts) {
    int w = 0;
    for (const auto& p : parts) w = std::max(w, p.cols);
    std::vector<cv::Mat> padded;
    for (const auto& p : parts) {
        cv::Mat q(p.rows, w, CV_8UC3, kPanel);
        p.copyTo(q(cv::Rect(0, 0, p.cols, p.rows)));
        padded.push_back(q);
    }
    cv::Mat out;
    cv::vconcat(padded, out);
    return out;
}

std::string summary_line(const retina::CubeResult& r) {
    return "CFT " + printf_number("%.0f um", r.cft_mm * 1e3) + "   rim height " +
           printf_number("%.0f um", r.rim_height_mm * 1e3) + "   pit depth " +
           printf_number("%.0f um", r.pit_depth_mm * 1e3) + "   max slope " +
           printf_number("%.1f deg", r.max_pit_slope_deg) + "   fit RMSE " +
           printf_number("%.2f um", r.rmse_um);
}

// The thickness colour range: from just below CFT to just above the highest valid thickness.
std::pair<double, double> thickness_range(const retina::CubeResult& r) {
    double lo = r.cft_mm - 0.02;
    double hi = lo + 0.1;
    for (const double v : r.map.mm) {
        if (!std::isnan(v)) hi = std::max(hi, v);
    }
    return {lo, hi + 0.01};
}

// A volume's thickness map, with colour bar (um), 1 mm scale bar, the disks and the centre.
// The rim, slope and pit-flat disks (Eq. 7.16-7.18) as closed lines; to_px(x, y) maps grid mm
// to the picture's pixels.
template <class ToPx>
void draw_disks(cv::Mat& img, const retina::CubeResult& r, const ToPx& to_px) {
    const auto poly = [&](const retina::CubeDisk& d, const cv::Scalar& c) {
        if (d.points.empty()) return;
        std::vector<cv::Point> pts;
        for (const auto& p : d.points) pts.push_back(to_px(p.x(), p.y()));
        cv::polylines(img, pts, true, c, 2, cv::LINE_AA);
    };
    poly(r.rim, kRim);
    poly(r.slope, kSlope);
    poly(r.pit_flat, kFlat);
}

// The map in the fundus frame (fundus.h): superior up, whichever way the B-scans ran.
cv::Mat thickness_map_picture(const retina::CubeResult& r, const io::Scan& scan,
                              const std::string& title) {
    const retina::ThicknessMap& m = r.map;
    const FundusFrame ff = fundus_frame(scan, (m.cols - 1) * m.dx_mm, (m.rows - 1) * m.dy_mm);
    const int W = 800;
    const double px_per_mm = W / ff.width_mm;
    const cv::Mat values = fundus_thickness_raster(m, scan, W);
    const int H = values.rows;
    const auto [lo, hi] = thickness_range(r);
    cv::Mat grey(H, W, CV_8UC1);
    cv::Mat valid(H, W, CV_8UC1);
    for (int y = 0; y < H; ++y) {
        for (int x = 0; x < W; ++x) {
            const double v = values.at<double>(y, x);
            valid.at<uchar>(y, x) = std::isnan(v) ? 0 : 255;
            const double u = std::isnan(v) ? 0.0 : std::clamp((v - lo) / (hi - lo), 0.0, 1.0);
            grey.at<uchar>(y, x) = static_cast<uchar>(std::lround(255 * u));
        }
    }
    cv::Mat img;
    cv::applyColorMap(grey, img, cv::COLORMAP_VIRIDIS);
    img.setTo(cv::Scalar(60, 60, 60), valid == 0);
    auto to_px = [&](double gx, double gy) {
        const Eigen::Vector2d f = ff.to_fundus({gx, gy});
        return cv::Point(static_cast<int>(std::lround(f.x() * px_per_mm)),
                         static_cast<int>(std::lround(H - 1 - f.y() * px_per_mm)));
    };
    for (const auto& h : r.half_lines) {
        const Eigen::Vector2d e = r.centre_mm + h.r_mm.back() * h.direction;
        cv::line(img, to_px(r.centre_mm.x(), r.centre_mm.y()), to_px(e.x(), e.y()),
                 cv::Scalar(200, 200, 200), 1, cv::LINE_AA);
    }
    draw_disks(img, r, to_px);
    // Anatomical labels at the ends of the nasal, superior, temporal and inferior half-lines.
    for (const auto& h : r.half_lines) {
        const char* label = anatomical_label(h.angle_deg);
        if (label == nullptr) continue;
        const Eigen::Vector2d e = r.centre_mm + (h.r_mm.back() + 0.15) * h.direction;
        outlined_text(img, label, to_px(e.x(), e.y()) + cv::Point(-7, 7), 0.7,
                      palette::kWhite);
    }
    cv::drawMarker(img, to_px(r.centre_mm.x(), r.centre_mm.y()), kCentre, cv::MARKER_CROSS, 18, 2);
    scale_bar(img, {14, H - 16}, px_per_mm, palette::kWhite);

    const int bar_w = 130;
    cv::Mat body(H + 40, W + bar_w, CV_8UC3, kPanel);
    img.copyTo(body(cv::Rect(0, 30, W, H)));
    colour_bar(body, cv::Rect(W + 18, 30 + 6, 22, H - 12), lo, hi, cv::COLORMAP_VIRIDIS,
               "thickness (um)", 1e3, "%.0f");
    cv::Mat legend(74, W + bar_w, CV_8UC3, kPanel);
    draw_legend(legend, {8, 22},
                {{LegendItem::kLine, kRim, "rim"},
                 {LegendItem::kLine, kSlope, "steepest slope"},
                 {LegendItem::kLine, kFlat, "pit flat"},
                 {LegendItem::kCross, kCentre, "centre (" + r.centre_source + ")"},
                 {LegendItem::kLine, cv::Scalar(200, 200, 200), "half-lines"},
                 {LegendItem::kDot, cv::Scalar(60, 60, 60), "missing"}},
                0.45, kText, W + bar_w - 8);
    plain_text(legend, summary_line(r), {8, 60}, 0.45, kText);
    return stack({title_strip(W + bar_w, 34, title), body, legend});
}

// A line scan: thickness along the line (one row is no map), with the rim points and centre.
cv::Mat thickness_line_picture(const retina::CubeResult& r, const std::string& title) {
    const retina::ThicknessMap& m = r.map;
    const int W = 930;
    const int H = 400;
    cv::Mat img(H, W, CV_8UC3, palette::kWhite);
    const auto [lo, hi] = thickness_range(r);
    Axes a;
    a.plot = cv::Rect(70, 30, W - 100, H - 120);
    a.x0 = 0.0;
    a.x1 = (m.cols - 1) * m.dx_mm;
    a.y0 = lo;
    a.y1 = hi;
    draw_axes(img, a, "position along the line (mm)", "thickness (um)", "%.1f", "%.0f", 1e3,
              0.45, 8, 5);
    std::vector<cv::Point> pts;
    for (int c = 0; c < m.cols; ++c) {
        const double v = m.at(0, c);
        if (std::isnan(v)) {
            if (pts.size() > 1) cv::polylines(img, pts, false, cv::Scalar(60, 60, 60), 1, cv::LINE_AA);
            pts.clear();
            continue;
        }
        pts.push_back(a.px(c * m.dx_mm, v));
    }
    if (pts.size() > 1) cv::polylines(img, pts, false, cv::Scalar(60, 60, 60), 1, cv::LINE_AA);
    for (const auto& h : r.half_lines) {
        if (!h.valid) continue;
        const double x = r.centre_mm.x() + h.rim_radius_mm * h.direction.x();
        cv::circle(img, a.px(x, h.rim_height_mm), 6, kRim, 2, cv::LINE_AA);
    }
    cv::drawMarker(img, a.px(r.centre_mm.x(), r.cft_mm), kCentre, cv::MARKER_CROSS, 18, 2);
    draw_legend(img, {70, H - 12},
                {{LegendItem::kLine, cv::Scalar(60, 60, 60), "thickness ILM-BM"},
                 {LegendItem::kRing, kRim, "rim points"},
                 {LegendItem::kCross, kCentre, "centre, CFT (" + r.centre_source + ")"}},
                0.45, cv::Scalar(40, 40, 40), W - 10);
    cv::Mat foot(30, W, CV_8UC3, kPanel);
    plain_text(foot, summary_line(r), {8, 20}, 0.45, kText);
    return stack({title_strip(W, 34, title), img, foot});
}

cv::Mat profiles_picture(const retina::CubeResult& r, const std::string& title) {
    const int n = static_cast<int>(r.half_lines.size());
    const int cols = n <= 2 ? 2 : 6;
    const int rows = (n + cols - 1) / cols;
    const int pw = 300;
    const int ph = 200;
    cv::Mat img(rows * ph, cols * pw, CV_8UC3, palette::kWhite);
    double hmin = 1e9;
    double hmax = -1e9;
    double rmax = 0.0;
    for (const auto& h : r.half_lines) {
        for (std::size_t k = 0; k < h.h_mm.size(); ++k) {
            if (std::isnan(h.h_mm[k])) continue;
            hmin = std::min(hmin, h.h_mm[k]);
            hmax = std::max(hmax, h.h_mm[k]);
        }
        rmax = std::max(rmax, h.r_mm.back());
    }
    if (!(hmax > hmin)) {
        hmin = 0.0;
        hmax = 0.5;
    }
    hmin -= 0.01;
    hmax += 0.01;
    for (int i = 0; i < n; ++i) {
        const auto& h = r.half_lines[static_cast<std::size_t>(i)];
        const int ox = (i % cols) * pw;
        const int oy = (i / cols) * ph;
        Axes a;
        a.plot = cv::Rect(ox + 46, oy + 26, pw - 60, ph - 66);
        a.x0 = 0.0;
        a.x1 = rmax;
        a.y0 = hmin;
        a.y1 = hmax;
        // The unit above the tick labels, the title centred over the plot: they do not meet
        // (the unit was drawn where the title starts: "um 0 deg").
        draw_axes(img, a, "r (mm)", "", "%.1f", "%.0f", 1e3, 0.35, 4, 5);
        int unit_base = 0;
        const cv::Size unit =
            cv::getTextSize("um", cv::FONT_HERSHEY_SIMPLEX, 0.35, 1, &unit_base);
        plain_text(img, "um", {a.plot.x - 6 - unit.width, a.plot.y - 6}, 0.35,
                   cv::Scalar(60, 60, 60));
        if (h.valid) {
            for (const auto* fit : {&h.interior, &h.exterior}) {
                std::vector<cv::Point> pts;
                for (int k = 0; k <= 100; ++k) {
                    const Eigen::Vector2d q = retina::bezier_point(fit->control, k / 100.0);
                    pts.push_back(a.px(q.x(), q.y()));
                }
                cv::polylines(img, pts, false, fit == &h.interior ? kInterior : kExterior, 2,
                              cv::LINE_AA);
            }
        }
        for (std::size_t k = 0; k < h.h_mm.size(); k += 2) {
            if (!std::isnan(h.h_mm[k])) {
                cv::circle(img, a.px(h.r_mm[k], h.h_mm[k]), 1, cv::Scalar(60, 60, 60), -1);
            }
        }
        if (h.valid) {
            cv::circle(img, a.px(h.rim_radius_mm, h.rim_height_mm), 4, kRim, -1);
            cv::circle(img, a.px(h.slope_point.x(), h.slope_point.y()), 3,
                       cv::Scalar(0, 160, 220), -1);
        }
        const std::string t =
            printf_number("%.0f deg", h.angle_deg) +
            (h.valid ? "  RMSE " + printf_number("%.2f um", h.rmse_um) : "  FAILED");
        int title_base = 0;
        const cv::Size title_size =
            cv::getTextSize(t, cv::FONT_HERSHEY_SIMPLEX, 0.45, 1, &title_base);
        cv::putText(img, t, {a.plot.x + std::max(0, (a.plot.width - title_size.width) / 2), oy + 18},
                    cv::FONT_HERSHEY_SIMPLEX, 0.45,
                    h.valid ? cv::Scalar(0, 0, 0) : cv::Scalar(0, 0, 200), 1, cv::LINE_AA);
    }
    cv::Mat legend(56, img.cols, CV_8UC3, palette::kWhite);
    plain_text(legend,
               "thickness (um, y) against the distance r from the centre (mm, x) along each "
               "half-line (anatomical angle: 0 nasal, 90 superior)",
               {8, 18}, 0.45, cv::Scalar(20, 20, 20));
    draw_legend(legend, {8, 44},
                {{LegendItem::kDot, cv::Scalar(60, 60, 60), "samples"},
                 {LegendItem::kLine, kInterior, "interior Bezier fit"},
                 {LegendItem::kLine, kExterior, "exterior Bezier fit"},
                 {LegendItem::kDot, kRim, "rim point"},
                 {LegendItem::kDot, cv::Scalar(0, 160, 220), "steepest slope"}},
                0.45, cv::Scalar(20, 20, 20), img.cols - 8);
    return stack({title_strip(img.cols, 34, title), legend, img});
}

// The fitted thickness at position `p` (grid or radial mm) of a B-scan running along `u`: from
// the half-line along that B-scan (direction +-u) pointing towards p.
double fitted_thickness_at(const retina::CubeResult& r, const Eigen::Vector2d& u,
                           const Eigen::Vector2d& p) {
    for (const auto& h : r.half_lines) {
        if (std::fabs(h.direction.x() * u.y() - h.direction.y() * u.x()) > 1e-6) continue;
        const Eigen::Vector2d o = std::isnan(h.origin_mm.x()) ? r.centre_mm : h.origin_mm;
        const double rr = (p - o).dot(h.direction);
        if (rr < 0.0) continue;
        return retina::fitted_thickness_mm(h, rr);
    }
    return std::numeric_limits<double>::quiet_NaN();
}

// The B-scan through the centre with the device ILM and BM and the fitted profile drawn from
// BM up by the fitted thickness (along the nasal and temporal half-lines, which lie on it).
}  // namespace

cv::Mat fundus_thickness_raster(const retina::ThicknessMap& m, const io::Scan& scan,
                                int width_px) {
    const FundusFrame ff = fundus_frame(scan, (m.cols - 1) * m.dx_mm, (m.rows - 1) * m.dy_mm);
    const double px_per_mm = width_px / ff.width_mm;
    const int H = std::max(40, static_cast<int>(std::lround(ff.height_mm * px_per_mm)));
    cv::Mat out(H, width_px, CV_64FC1);
    for (int y = 0; y < H; ++y) {
        // Image row 0 at the top = the largest fundus y (superior).
        const double fy = (H - 1 - y) / px_per_mm;
        for (int x = 0; x < width_px; ++x) {
            const Eigen::Vector2d g = ff.to_grid({x / px_per_mm, fy});
            out.at<double>(y, x) = m.sample(g.x(), g.y());
        }
    }
    return out;
}

std::pair<double, double> macula_thickness_range(const retina::CubeResult& r) {
    return thickness_range(r);
}

cv::Point RadialThicknessLayout::px(double x_mm, double y_mm) const {
    return {static_cast<int>(std::lround(crossing.x + x_mm * ppm)),
            static_cast<int>(std::lround(crossing.y - y_mm * ppm))};
}

cv::Mat macula_radial_thickness_picture(const retina::CubeResult& r, const io::Scan& scan,
                                        const std::string& title,
                                        RadialThicknessLayout* layout_out) {
    const retina::RadialGeometry geo = retina::radial_geometry(scan);
    const retina::ThicknessMap& m = r.map;  // one row per line, one column per A-scan
    const int nx = scan.meta.size_x;
    const int nl = static_cast<int>(geo.lines.size());
    double reach = 0.5;
    for (int k = 0; k < nl; ++k) {
        reach = std::max({reach, geo.ascan_mm(k, 0.0, nx).norm(),
                          geo.ascan_mm(k, nx - 1.0, nx).norm()});
    }
    reach += 0.25;  // room for the lines' numbers
    const int W = 800;
    RadialThicknessLayout L;
    L.ppm = W / (2.0 * reach);
    L.crossing = {0.5 * W, 0.5 * W};
    const auto [lo, hi] = thickness_range(r);
    cv::Mat ramp(1, 256, CV_8UC1);
    for (int i = 0; i < 256; ++i) ramp.at<uchar>(0, i) = static_cast<uchar>(i);
    cv::Mat lut;
    cv::applyColorMap(ramp, lut, cv::COLORMAP_VIRIDIS);
    cv::Mat img(W, W, CV_8UC3, kPanel);
    // Each line where it was scanned, 7 px wide, coloured by its own thickness A-scan by
    // A-scan (nothing is interpolated between the lines).
    const cv::Scalar missing(110, 110, 110);
    for (int k = 0; k < nl; ++k) {
        for (int a = 0; a + 1 < nx && a + 1 < m.cols; ++a) {
            const Eigen::Vector2d p = geo.ascan_mm(k, a, nx);
            const Eigen::Vector2d q = geo.ascan_mm(k, a + 1.0, nx);
            const double v = k < m.rows ? m.at(k, a) : std::numeric_limits<double>::quiet_NaN();
            cv::Scalar c = missing;
            if (!std::isnan(v)) {
                const int i = static_cast<int>(
                    std::lround(255 * std::clamp((v - lo) / (hi - lo), 0.0, 1.0)));
                const cv::Vec3b& b = lut.at<cv::Vec3b>(0, i);
                c = cv::Scalar(b[0], b[1], b[2]);
            }
            cv::line(img, L.px(p.x(), p.y()), L.px(q.x(), q.y()), c, 7, cv::LINE_8);
        }
        const Eigen::Vector2d e = geo.ascan_mm(k, nx - 1.0, nx);
        const Eigen::Vector2d u = geo.direction(k);
        const cv::Point t = L.px(e.x() + 0.12 * u.x(), e.y() + 0.12 * u.y()) + cv::Point(-6, 5);
        outlined_text(img, std::to_string(k), t, 0.4, cv::Scalar(200, 200, 200));
    }
    draw_disks(img, r, [&](double x, double y) { return L.px(x, y); });
    for (const auto& h : r.half_lines) {
        const char* label = anatomical_label(h.angle_deg);
        if (label == nullptr || h.r_mm.empty()) continue;
        const Eigen::Vector2d o = std::isnan(h.origin_mm.x()) ? r.centre_mm : h.origin_mm;
        const Eigen::Vector2d e = o + 0.5 * h.r_mm.back() * h.direction;
        const Eigen::Vector2d side(-h.direction.y(), h.direction.x());
        const Eigen::Vector2d at = e + 0.2 * side;
        outlined_text(img, label, L.px(at.x(), at.y()) + cv::Point(-7, 7), 0.7, palette::kWhite);
    }
    cv::drawMarker(img, L.px(0.0, 0.0), palette::kCyan, cv::MARKER_TILTED_CROSS, 14, 2);
    cv::drawMarker(img, L.px(r.centre_mm.x(), r.centre_mm.y()), kCentre, cv::MARKER_CROSS, 18, 2);
    scale_bar(img, {14, W - 16}, L.ppm, palette::kWhite);

    const int bar_w = 130;
    cv::Mat body(W + 40, W + bar_w, CV_8UC3, kPanel);
    img.copyTo(body(cv::Rect(0, 30, W, W)));
    colour_bar(body, cv::Rect(W + 18, 30 + 6, 22, W - 12), lo, hi, cv::COLORMAP_VIRIDIS,
               "thickness (um)", 1e3, "%.0f");
    cv::Mat legend(100, W + bar_w, CV_8UC3, kPanel);
    const int end = draw_legend(
        legend, {8, 22},
        {{LegendItem::kLine, cv::Scalar(lut.at<cv::Vec3b>(0, 128)),
          "thickness along each line (B-scan number from 0 at its End)"},
         {LegendItem::kDot, missing, "missing"},
         {LegendItem::kLine, kRim, "rim"},
         {LegendItem::kLine, kSlope, "steepest slope"},
         {LegendItem::kLine, kFlat, "pit flat"},
         {LegendItem::kCross, kCentre, "centre (" + r.centre_source + ")"},
         {LegendItem::kTiltedCross, palette::kCyan, "line crossing"}},
        0.45, kText, W + bar_w - 8);
    plain_text(legend, summary_line(r), {8, end + 14}, 0.45, kText);
    if (layout_out != nullptr) {
        *layout_out = L;
        layout_out->crossing.y += 34 + 30;  // the title strip and the body's top margin
    }
    return stack({title_strip(W + bar_w, 34, title), body, legend});
}

// What the lateral registration did to B-scan b, as the ONH pictures say it (draw.h): the shift
// it moved the lines by (rounded to whole A-scans of um_per_ascan when whole_ascans).
static std::string lateral_title(const retina::LateralRegistration& l, int b, double um_per_ascan) {
    if (!l.applied || b < 0 || static_cast<std::size_t>(b) >= l.shift_um.size()) return "";
    double moved = l.shift_um[static_cast<std::size_t>(b)];
    if (l.whole_ascans && um_per_ascan > 0.0) moved = std::round(moved / um_per_ascan) * um_per_ascan;
    return registration_title(0.0, moved);
}

cv::Mat macula_bscan_picture(const retina::CubeResult& r, const io::Scan& scan,
                             const std::string& title, int* bscan_out) {
    const int nb = scan.num_bscans();
    // Where A-scan a of the B-scan lies (grid mm, or radial mm), and its direction.
    std::optional<retina::RadialGeometry> geo;
    if (r.radial_scan) geo = retina::radial_geometry(scan);
    int b = r.line_scan || r.map.dy_mm <= 0.0
                ? 0
                : std::clamp(static_cast<int>(std::lround(r.centre_mm.y() / r.map.dy_mm)), 0,
                             nb - 1);
    if (geo) {
        // The line nearest to the horizontal (nasal-temporal), as a device shows first.
        double best = 2.0;
        for (int k = 0; k < static_cast<int>(geo->lines.size()); ++k) {
            const double s = std::fabs(geo->direction(k).y());
            if (s < best - 1e-9) {
                best = s;
                b = k;
            }
        }
    }
    const Eigen::Vector2d u = geo ? geo->direction(b) : Eigen::Vector2d(1.0, 0.0);
    auto position = [&](double a) -> Eigen::Vector2d {
        if (geo) return geo->ascan_mm(b, a, scan.meta.size_x);
        return {a * r.map.dx_mm, b * r.map.dy_mm};
    };
    if (bscan_out != nullptr) *bscan_out = b;
    const io::BScan& bs = scan.bscans[static_cast<std::size_t>(b)];
    const int w = scan.meta.size_x;
    const int h = scan.meta.size_z;
    const bool pixels = bs.pixels.size() == static_cast<std::size_t>(w) * static_cast<std::size_t>(h);
    const cv::Mat grey = bscan_grey(bs, w, h);
    // Shown at 900 px wide, the depth stretched by the same factor as the width (pixels keep
    // the device's aspect: one row per depth pixel).
    const int W = 900;
    const double sx = static_cast<double>(W) / w;
    const int H = std::max(120, static_cast<int>(std::lround(h * sx * 0.5)));
    const double sz = static_cast<double>(H) / h;
    cv::Mat big;
    cv::resize(grey, big, cv::Size(W, H), 0, 0, cv::INTER_AREA);
    cv::Mat img;
    cv::cvtColor(big, img, cv::COLOR_GRAY2BGR);
    auto line_of = [&](int k) -> const std::vector<float>* {
        return bs.has_line(k) ? &bs.seg[static_cast<std::size_t>(k)] : nullptr;
    };
    // A-scan a and depth pixel z (values at pixel centres) to picture pixels.
    auto pt = [&](double a, double z) {
        return cv::Point(static_cast<int>(std::lround((a + 0.5) * sx)),
                         static_cast<int>(std::lround((z + 0.5) * sz)));
    };
    auto draw = [&](const std::vector<float>* line, cv::Scalar c) {
        if (line == nullptr) return;
        for (std::size_t a = 0; a + 1 < line->size(); ++a) {
            if (!io::is_valid((*line)[a]) || !io::is_valid((*line)[a + 1])) continue;
            cv::line(img, pt(static_cast<double>(a), (*line)[a]),
                     pt(static_cast<double>(a + 1), (*line)[a + 1]), c, 1, cv::LINE_AA);
        }
    };
    const auto* bm = line_of(static_cast<int>(io::Layer::kBM));
    draw(bm, kBm);
    draw(line_of(static_cast<int>(io::Layer::kILM)), kIlm);
    if (bm != nullptr && scan.meta.scale_z_mm > 0.0) {
        std::vector<cv::Point> pts;
        for (int a = 0; a < w && a < static_cast<int>(bm->size()); ++a) {
            const double t = fitted_thickness_at(r, u, position(a));
            if (std::isnan(t) || !io::is_valid((*bm)[static_cast<std::size_t>(a)])) {
                if (pts.size() > 1) cv::polylines(img, pts, false, kFit, 2, cv::LINE_AA);
                pts.clear();
                continue;
            }
            pts.push_back(pt(a, (*bm)[static_cast<std::size_t>(a)] - t / scan.meta.scale_z_mm));
        }
        if (pts.size() > 1) cv::polylines(img, pts, false, kFit, 2, cv::LINE_AA);
    }
    // The centre's A-scan: its foot on the B-scan.
    const Eigen::Vector2d p0 = position(0.0);
    const double step = (position(w - 1.0) - p0).norm() / std::max(1, w - 1);
    const double a_centre = step > 0.0 ? (r.centre_mm - p0).dot(u) / step : 0.0;
    const int cx = static_cast<int>(std::lround((a_centre + 0.5) * sx));
    cv::line(img, {cx, 0}, {cx, H - 1}, kCentre, 1, cv::LINE_AA);
    outlined_text(img,
                  "B-scan " + std::to_string(b) +
                      (nb > 1 ? " of 0-" + std::to_string(nb - 1) : std::string()) +
                      (geo ? printf_number(" (through the centre, %.0f deg)",
                                           geo->lines[static_cast<std::size_t>(b)].angle_deg)
                           : std::string(" (through the centre)")) +
                      (pixels ? ""
                              : scan.meta.format == io::SourceFormat::kIowaSurfaces
                                    ? "; a segmentation file has no pixels"
                                    : "; the export has no pixels") +
                      lateral_title(r.lateral_registration, b, scan.meta.scale_x_mm * 1000.0),
                  {10, 24}, 0.55, palette::kWhite);
    scale_bar(img, {14, H - 14}, W / (w * scan.meta.scale_x_mm), palette::kWhite);

    // Axes around the picture: x in mm, depth in um (from the top of the B-scan).
    cv::Mat framed(H + 72, W + 90, CV_8UC3, palette::kWhite);
    img.copyTo(framed(cv::Rect(70, 24, W, H)));
    Axes a;
    a.plot = cv::Rect(70, 24, W, H);
    // Grid x = a · ScaleX at the centre of A-scan a; depth z · ScaleZ at the centre of row z.
    a.x0 = -0.5 * scan.meta.scale_x_mm;
    a.x1 = (w - 0.5) * scan.meta.scale_x_mm;
    a.y0 = -(h - 0.5) * scan.meta.scale_z_mm;  // y up: depth 0 at the top
    a.y1 = 0.5 * scan.meta.scale_z_mm;
    draw_axes(framed, a, "x along the B-scan (mm)", "depth (um, from the top)", "%.1f", "%.0f",
              -1e3, 0.42, 8, 5);
    img.copyTo(framed(cv::Rect(70, 24, W, H)));  // the grid lines stay outside the picture
    cv::rectangle(framed, a.plot, cv::Scalar(60, 60, 60), 1);
    cv::Mat legend(40, framed.cols, CV_8UC3, kPanel);
    // Whose lines they are: the device's, or a segmentation laid over or read alone.
    // The export's own lines (a Topcon file names its contours, and they are the device's).
    const bool own = scan.line_names.empty() || scan.meta.format == io::SourceFormat::kTopcon;
    draw_legend(legend, {8, 26},
                {{LegendItem::kLine, kIlm, own ? "ILM (device)" : "ILM (segmentation file)"},
                 {LegendItem::kLine, kBm, own ? "BM (device)" : "BM (segmentation file)"},
                 {LegendItem::kLine, kFit, "fitted profile (BM + fitted thickness)"},
                 {LegendItem::kLine, kCentre, "centre"}},
                0.45, kText, framed.cols - 8);
    return stack({title_strip(framed.cols, 34, title), framed, legend});
}

void write_macula_qc(const retina::CubeResult& r, const io::Scan& scan, const std::string& dir,
                     const std::string& stem) {
    const std::filesystem::path d = qc_directory(dir);
    const std::string title = scan_title(scan.meta, scan.num_bscans());
    const bool one_row = r.line_scan || r.map.rows < 2;
    // A radial scan's map rows are its lines, not a grid: the thickness is drawn along them.
    // Every picture is drawn before any is written: a drawing error leaves no picture behind.
    const cv::Mat t = r.radial_scan ? macula_radial_thickness_picture(r, scan, title)
                      : one_row     ? thickness_line_picture(r, title)
                                    : thickness_map_picture(r, scan, title);
    const cv::Mat p = profiles_picture(r, title);
    const cv::Mat b = macula_bscan_picture(r, scan, title);
    save_png(t, (d / picture_name(stem, kind::kThickness)).string());
    save_png(p, (d / picture_name(stem, kind::kProfiles)).string());
    save_png(b, (d / picture_name(stem, kind::kBscan)).string());
}

}  // namespace octshape::qc
