#include "commands/qc_draw.h"

#include <cstdint>
#include <cstdio>
#include <span>
#include <opencv2/imgproc.hpp>
#include <string_view>
#include <vector>

#include "octshape/io/atomic_file.h"
#include "octshape/error.h"
#include "octshape/io/image.h"

namespace octshape::app {

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

void outlined_text(cv::Mat& img, const std::string& s, cv::Point p, double scale, cv::Scalar c) {
    cv::putText(img, s, p, cv::FONT_HERSHEY_SIMPLEX, scale, cv::Scalar(0, 0, 0), 3, cv::LINE_AA);
    cv::putText(img, s, p, cv::FONT_HERSHEY_SIMPLEX, scale, c, 1, cv::LINE_AA);
}

}  // namespace octshape::app
