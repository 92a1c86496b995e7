#include "commands/macula_qc.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <vector>

#include "commands/qc_draw.h"
#include "octshape/error.h"

namespace octshape::app {
namespace {

const cv::Scalar kRim(40, 40, 230);        // red (BGR)
const cv::Scalar kSlope(0, 200, 255);      // yellow
const cv::Scalar kFlat(255, 255, 255);     // white
const cv::Scalar kInterior(60, 180, 60);   // green
const cv::Scalar kExterior(220, 120, 30);  // blue

cv::Mat thickness_picture(const retina::CubeResult& r) {
    const retina::ThicknessMap& m = r.map;
    const double width_mm = (m.cols - 1) * m.dx_mm;
    const double height_mm = std::max(m.rows - 1, 1) * (m.rows > 1 ? m.dy_mm : m.dx_mm);
    const int W = 800;
    const double px_per_mm = W / width_mm;
    const int H = std::max(40, static_cast<int>(std::lround(height_mm * px_per_mm)));
    // Colour scale from just below CFT to just above the highest valid thickness.
    double lo = r.cft_mm - 0.02;
    double hi = lo + 0.1;
    for (const double v : m.mm) {
        if (!std::isnan(v)) hi = std::max(hi, v);
    }
    hi += 0.01;
    cv::Mat grey(H, W, CV_8UC1);
    cv::Mat valid(H, W, CV_8UC1);
    for (int y = 0; y < H; ++y) {
        // Image row 0 at the top = largest grid y (superior for the usual placement).
        const double gy = m.rows > 1 ? (H - 1 - y) / px_per_mm : 0.0;
        for (int x = 0; x < W; ++x) {
            const double v = m.sample(x / px_per_mm, gy);
            valid.at<uchar>(y, x) = std::isnan(v) ? 0 : 255;
            const double u = std::isnan(v) ? 0.0 : std::clamp((v - lo) / (hi - lo), 0.0, 1.0);
            grey.at<uchar>(y, x) = static_cast<uchar>(std::lround(255 * u));
        }
    }
    cv::Mat img;
    cv::applyColorMap(grey, img, cv::COLORMAP_VIRIDIS);
    img.setTo(cv::Scalar(60, 60, 60), valid == 0);
    auto to_px = [&](double gx, double gy) {
        return cv::Point(static_cast<int>(std::lround(gx * px_per_mm)),
                         static_cast<int>(std::lround(H - 1 - gy * px_per_mm)));
    };
    for (const auto& h : r.half_lines) {
        const Eigen::Vector2d e = r.centre_mm + h.r_mm.back() * h.direction;
        cv::line(img, to_px(r.centre_mm.x(), r.centre_mm.y()), to_px(e.x(), e.y()),
                 cv::Scalar(200, 200, 200), 1, cv::LINE_AA);
    }
    auto poly = [&](const retina::CubeDisk& d, cv::Scalar c) {
        if (d.points.empty()) return;
        std::vector<cv::Point> pts;
        for (const auto& p : d.points) pts.push_back(to_px(p.x(), p.y()));
        cv::polylines(img, pts, true, c, 2, cv::LINE_AA);
    };
    poly(r.rim, kRim);
    poly(r.slope, kSlope);
    poly(r.pit_flat, kFlat);
    if (r.line_scan) {
        for (const auto& h : r.half_lines) {
            if (!h.valid) continue;
            const Eigen::Vector2d q = r.centre_mm + h.rim_radius_mm * h.direction;
            cv::circle(img, to_px(q.x(), q.y()), 6, kRim, 2, cv::LINE_AA);
        }
    }
    // Anatomical labels at the ends of the nasal (0 deg) and superior (90 deg) half-lines.
    for (const auto& h : r.half_lines) {
        const char* label = h.angle_deg == 0.0 ? "N" : (h.angle_deg == 90.0 ? "S" : nullptr);
        if (label == nullptr) continue;
        const Eigen::Vector2d e = r.centre_mm + (h.r_mm.back() + 0.15) * h.direction;
        outlined_text(img, label, to_px(e.x(), e.y()) + cv::Point(-7, 7), 0.7,
                      cv::Scalar(255, 255, 255));
    }
    const cv::Point c = to_px(r.centre_mm.x(), r.centre_mm.y());
    cv::drawMarker(img, c, cv::Scalar(255, 0, 255), cv::MARKER_CROSS, 18, 2);
    // Legend strip.
    cv::Mat out(H + 70, W, CV_8UC3, cv::Scalar(30, 30, 30));
    img.copyTo(out(cv::Rect(0, 0, W, H)));
    outlined_text(out,
                  "thickness " + printf_number("%.2f", lo) + " (dark) - " +
                      printf_number("%.2f", hi) + " mm (yellow); grey = missing; + centre (" +
                      r.centre_source + ")",
                  {8, H + 22}, 0.5, cv::Scalar(230, 230, 230));
    outlined_text(out, "rim", {8, H + 52}, 0.6, kRim);
    outlined_text(out, "slope", {60, H + 52}, 0.6, kSlope);
    outlined_text(out, "pit flat", {135, H + 52}, 0.6, kFlat);
    outlined_text(out,
                  "CFT " + printf_number("%.3f", r.cft_mm) + " mm  rim " +
                      printf_number("%.3f", r.rim_height_mm) + " mm  slope " +
                      printf_number("%.1f", r.max_pit_slope_deg) + " deg  RMSE " +
                      printf_number("%.2f", r.rmse_um) + " um",
                  {250, H + 52}, 0.5, cv::Scalar(230, 230, 230));
    return out;
}

cv::Mat profiles_picture(const retina::CubeResult& r) {
    const int n = static_cast<int>(r.half_lines.size());
    const int cols = n <= 2 ? 2 : 6;
    const int rows = (n + cols - 1) / cols;
    const int pw = 260;
    const int ph = 170;
    cv::Mat img(rows * ph, cols * pw, CV_8UC3, cv::Scalar(255, 255, 255));
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
    hmin -= 0.01;
    hmax += 0.01;
    for (int i = 0; i < n; ++i) {
        const auto& h = r.half_lines[static_cast<std::size_t>(i)];
        const int ox = (i % cols) * pw;
        const int oy = (i / cols) * ph;
        const cv::Rect plot(ox + 30, oy + 24, pw - 40, ph - 44);
        cv::rectangle(img, plot, cv::Scalar(200, 200, 200), 1);
        auto to_px = [&](double rr, double hh) {
            return cv::Point(
                plot.x + static_cast<int>(std::lround(rr / rmax * plot.width)),
                plot.y + plot.height -
                    static_cast<int>(std::lround((hh - hmin) / (hmax - hmin) * plot.height)));
        };
        if (h.valid) {
            for (const auto* fit : {&h.interior, &h.exterior}) {
                std::vector<cv::Point> pts;
                for (int k = 0; k <= 100; ++k) {
                    const Eigen::Vector2d q = retina::bezier_point(fit->control, k / 100.0);
                    pts.push_back(to_px(q.x(), q.y()));
                }
                cv::polylines(img, pts, false, fit == &h.interior ? kInterior : kExterior, 1,
                              cv::LINE_AA);
            }
        }
        for (std::size_t k = 0; k < h.h_mm.size(); k += 2) {
            if (!std::isnan(h.h_mm[k]))
                cv::circle(img, to_px(h.r_mm[k], h.h_mm[k]), 1, cv::Scalar(60, 60, 60), -1);
        }
        if (h.valid) {
            cv::circle(img, to_px(h.rim_radius_mm, h.rim_height_mm), 4, kRim, -1);
            cv::circle(img, to_px(h.slope_point.x(), h.slope_point.y()), 3, cv::Scalar(0, 160, 220),
                       -1);
        }
        const std::string title =
            printf_number("%.0f deg", h.angle_deg) +
            (h.valid ? "  RMSE " + printf_number("%.2f um", h.rmse_um) : "  FAILED");
        cv::putText(img, title, {ox + 30, oy + 17}, cv::FONT_HERSHEY_SIMPLEX, 0.45,
                    h.valid ? cv::Scalar(0, 0, 0) : cv::Scalar(0, 0, 200), 1, cv::LINE_AA);
        cv::putText(img, printf_number("%.2f", hmax), {ox + 2, plot.y + 8},
                    cv::FONT_HERSHEY_SIMPLEX, 0.3, cv::Scalar(90, 90, 90), 1, cv::LINE_AA);
        cv::putText(img, printf_number("%.2f", hmin), {ox + 2, plot.y + plot.height},
                    cv::FONT_HERSHEY_SIMPLEX, 0.3, cv::Scalar(90, 90, 90), 1, cv::LINE_AA);
        cv::putText(img, printf_number("r %.1f mm", rmax),
                    {plot.x + plot.width - 52, plot.y + plot.height + 14}, cv::FONT_HERSHEY_SIMPLEX,
                    0.3, cv::Scalar(90, 90, 90), 1, cv::LINE_AA);
    }
    return img;
}

}  // namespace

void write_macula_qc(const retina::CubeResult& r, const std::string& dir, const std::string& stem) {
    std::error_code ec;
    std::filesystem::create_directories(dir, ec);
    if (ec) throw OutputError(dir, "cannot create the QC directory: " + ec.message());
    const std::filesystem::path d(dir);
    save_png(thickness_picture(r), (d / (stem + "_thickness.png")).string());
    save_png(profiles_picture(r), (d / (stem + "_profiles.png")).string());
}

}  // namespace octshape::app
