#include "octshape/qc/draw.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <span>
#include <opencv2/imgproc.hpp>
#include <string_view>
#include <vector>

#include "octshape/io/atomic_file.h"
#include "octshape/error.h"
#include "octshape/io/image.h"

namespace octshape::qc {

void save_png(const cv::Mat& img, const std::string& path) {
    cv::Mat px;
    if (img.type() == CV_8UC3) {
        cv::cvtColor(img, px, cv::COLOR_BGR2RGB);  // OpenCV draws in BGR order
    } else if (img.type() == CV_8UC1) {
        px = img.isContinuous() ? img : img.clone();
    } else {
        throw OutputError(path, "PNG encoding failed: not an 8-bit grey or colour picture");
    }
    const std::string png = io::encode_png(
        px.cols, px.rows, px.channels(),
        std::span<const std::uint8_t>(px.data, px.total() * px.elemSize()));
    io::write_text_atomically(path, png);
}

std::string printf_number(const char* format, double value) {
    char b[128];
    std::snprintf(b, sizeof b, format, value);
    return b;
}

std::string registration_title(double up_um, double left_um) {
    const double up = std::fabs(up_um) < 0.5 ? 0.0 : up_um;
    const double left = std::fabs(left_um) < 0.5 ? 0.0 : left_um;
    std::string t;
    if (up != 0.0) t = printf_number(up > 0.0 ? ", moved %.0f um up" : ", moved %.0f um down", std::fabs(up));
    if (left != 0.0) {
        t += printf_number(t.empty() ? (left > 0.0 ? ", moved %.0f um left" : ", moved %.0f um right")
                                     : (left > 0.0 ? ", %.0f um left" : ", %.0f um right"),
                           std::fabs(left));
    }
    return t;
}

void outlined_text(cv::Mat& img, const std::string& s, cv::Point p, double scale, cv::Scalar c) {
    cv::putText(img, s, p, cv::FONT_HERSHEY_SIMPLEX, scale, cv::Scalar(0, 0, 0), 3, cv::LINE_AA);
    cv::putText(img, s, p, cv::FONT_HERSHEY_SIMPLEX, scale, c, 1, cv::LINE_AA);
}

void plain_text(cv::Mat& img, const std::string& s, cv::Point p, double scale, cv::Scalar c) {
    cv::putText(img, s, p, cv::FONT_HERSHEY_SIMPLEX, scale, c, 1, cv::LINE_AA);
}

std::string scan_title(const io::ScanMeta& meta, int num_bscans) {
    std::string t(io::to_string(meta.laterality));
    t += ", " + std::string(io::to_string(meta.pattern)) + " scan (pattern " +
         std::to_string(meta.scan_pattern_code) + "), ";
    t += std::to_string(num_bscans) + (num_bscans == 1 ? " B-scan x " : " B-scans x ") +
         std::to_string(meta.size_x) + " A-scans, ";
    const double w = meta.size_x * meta.scale_x_mm;
    if (num_bscans > 1 && meta.distance_mm > 0.0) {
        t += printf_number("%.2f", w) + " x " +
             printf_number("%.2f mm", (num_bscans - 1) * meta.distance_mm);
    } else {
        t += printf_number("%.2f mm", w);
    }
    return t;
}

std::filesystem::path qc_directory(const std::string& dir) {
    std::error_code ec;
    std::filesystem::create_directories(dir, ec);
    if (ec) throw OutputError(dir, "cannot create the QC directory: " + ec.message());
    return dir;
}

const char* anatomical_label(double deg) {
    if (deg == 0.0) return "N";
    if (deg == 90.0) return "S";
    if (deg == 180.0) return "T";
    if (deg == 270.0) return "I";
    return nullptr;
}

std::vector<double> nice_ticks(double lo, double hi, int count) {
    std::vector<double> t;
    if (!(hi > lo) || !std::isfinite(lo) || !std::isfinite(hi) || count < 1) return t;
    const double raw = (hi - lo) / count;
    const double mag = std::pow(10.0, std::floor(std::log10(raw)));
    double step = mag;
    for (const double m : {1.0, 2.0, 5.0, 10.0}) {
        step = m * mag;
        if (step >= raw) break;
    }
    for (double v = std::ceil(lo / step - 1e-9) * step; v <= hi + 1e-9 * step; v += step) {
        t.push_back(std::fabs(v) < 1e-12 * step ? 0.0 : v);
    }
    return t;
}

cv::Point Axes::px(double x, double y) const {
    const double u = (x - x0) / (x1 - x0);
    const double v = (y - y0) / (y1 - y0);
    return {plot.x + static_cast<int>(std::lround(u * plot.width)),
            plot.y + plot.height - static_cast<int>(std::lround(v * plot.height))};
}

void draw_axes(cv::Mat& img, const Axes& a, const std::string& xlabel, const std::string& ylabel,
               const char* xfmt, const char* yfmt, double yscale, double font, int xticks,
               int yticks) {
    const cv::Scalar ink(60, 60, 60);
    const cv::Scalar grid(225, 225, 225);
    for (const double x : nice_ticks(a.x0, a.x1, xticks)) {
        const cv::Point p = a.px(x, a.y0);
        cv::line(img, {p.x, a.plot.y}, {p.x, a.plot.y + a.plot.height}, grid, 1);
        cv::line(img, p, p + cv::Point(0, 4), ink, 1);
        const std::string s = printf_number(xfmt, x);
        int base = 0;
        const cv::Size sz = cv::getTextSize(s, cv::FONT_HERSHEY_SIMPLEX, font, 1, &base);
        plain_text(img, s, p + cv::Point(-sz.width / 2, 6 + sz.height), font, ink);
    }
    for (const double y : nice_ticks(a.y0, a.y1, yticks)) {
        const cv::Point p = a.px(a.x0, y);
        cv::line(img, {a.plot.x, p.y}, {a.plot.x + a.plot.width, p.y}, grid, 1);
        cv::line(img, p, p - cv::Point(4, 0), ink, 1);
        const std::string s = printf_number(yfmt, y * yscale + 0.0);  // + 0.0: no "-0"
        int base = 0;
        const cv::Size sz = cv::getTextSize(s, cv::FONT_HERSHEY_SIMPLEX, font, 1, &base);
        plain_text(img, s, p + cv::Point(-6 - sz.width, sz.height / 2), font, ink);
    }
    cv::rectangle(img, a.plot, ink, 1);
    int base = 0;
    const cv::Size xs = cv::getTextSize(xlabel, cv::FONT_HERSHEY_SIMPLEX, font, 1, &base);
    plain_text(img, xlabel,
               {a.plot.x + (a.plot.width - xs.width) / 2, a.plot.y + a.plot.height + 14 + 2 * xs.height},
               font, ink);
    plain_text(img, ylabel, {a.plot.x - 4, a.plot.y - 6}, font, ink);
}

void colour_bar(cv::Mat& img, cv::Rect where, double lo, double hi, int map,
                const std::string& caption, double label_scale, const char* fmt) {
    cv::Mat grey(where.height, 1, CV_8UC1);
    for (int y = 0; y < where.height; ++y) {
        grey.at<uchar>(y, 0) = static_cast<uchar>(
            std::lround(255.0 * (where.height - 1 - y) / std::max(1, where.height - 1)));
    }
    cv::Mat col;
    cv::applyColorMap(grey, col, map);
    cv::Mat wide;
    cv::resize(col, wide, where.size(), 0, 0, cv::INTER_NEAREST);
    wide.copyTo(img(where));
    const cv::Scalar ink(230, 230, 230);
    cv::rectangle(img, where, ink, 1);
    for (const double v : nice_ticks(lo, hi, 5)) {
        const int y = where.y + where.height - 1 -
                      static_cast<int>(std::lround((v - lo) / (hi - lo) * (where.height - 1)));
        cv::line(img, {where.x + where.width, y}, {where.x + where.width + 5, y}, ink, 1);
        plain_text(img, printf_number(fmt, v * label_scale), {where.x + where.width + 8, y + 5},
                   0.45, ink);
    }
    int base = 0;
    const int cw = cv::getTextSize(caption, cv::FONT_HERSHEY_SIMPLEX, 0.45, 1, &base).width;
    plain_text(img, caption, {std::max(0, std::min(where.x - 10, img.cols - cw - 4)), where.y - 10},
               0.45, ink);
}

cv::Mat bscan_grey(const io::BScan& bs, int size_x, int size_z) {
    cv::Mat grey(size_z, size_x, CV_8UC1, cv::Scalar(0));
    const auto w = static_cast<std::size_t>(size_x);
    if (bs.pixels.size() != w * static_cast<std::size_t>(size_z)) return grey;
    for (int z = 0; z < size_z; ++z) {
        for (int x = 0; x < size_x; ++x) {
            const float v = bs.pixels[static_cast<std::size_t>(z) * w + static_cast<std::size_t>(x)];
            const double d = (v >= io::kNoPixelData || !(v > 0.0F))
                                 ? 0.0
                                 : std::pow(static_cast<double>(v), 0.25);  // display
            grey.at<uchar>(z, x) = static_cast<uchar>(std::lround(255 * std::clamp(d, 0.0, 1.0)));
        }
    }
    return grey;
}

void scale_bar(cv::Mat& img, cv::Point p, double px_per_mm, cv::Scalar c) {
    const int len = static_cast<int>(std::lround(px_per_mm));
    cv::rectangle(img, p - cv::Point(0, 3), p + cv::Point(len, 3), cv::Scalar(0, 0, 0), -1);
    cv::rectangle(img, p - cv::Point(-1, 2), p + cv::Point(len - 1, 2), c, -1);
    outlined_text(img, "1 mm", p + cv::Point(std::max(0, len / 2 - 18), -9), 0.5, c);
}

int draw_legend(cv::Mat& img, cv::Point p, const std::vector<LegendItem>& items, double font,
                cv::Scalar text, int max_x) {
    int x = p.x;
    int y = p.y;
    for (const auto& it : items) {
        int base = 0;
        const cv::Size sz = cv::getTextSize(it.label, cv::FONT_HERSHEY_SIMPLEX, font, 1, &base);
        const int w = 26 + sz.width + 18;
        if (x + w > max_x && x > p.x) {
            x = p.x;
            y += sz.height + 12;
        }
        const cv::Point mid(x + 10, y - sz.height / 2);
        switch (it.kind) {
            case LegendItem::kLine:
                cv::line(img, mid - cv::Point(9, 0), mid + cv::Point(9, 0), it.colour, 2,
                         cv::LINE_AA);
                break;
            case LegendItem::kDot:
                cv::circle(img, mid, 4, it.colour, -1, cv::LINE_AA);
                break;
            case LegendItem::kRing:
                cv::circle(img, mid, 5, it.colour, 1, cv::LINE_AA);
                break;
            case LegendItem::kCross:
                cv::drawMarker(img, mid, it.colour, cv::MARKER_CROSS, 12, 2);
                break;
            case LegendItem::kTiltedCross:
                cv::drawMarker(img, mid, it.colour, cv::MARKER_TILTED_CROSS, 10, 2);
                break;
        }
        plain_text(img, it.label, {x + 24, y}, font, text);
        x += w;
    }
    return y + 10;
}

}  // namespace octshape::qc
