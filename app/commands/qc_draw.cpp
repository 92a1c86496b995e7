#include "commands/qc_draw.h"

#include <cstdio>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <string_view>
#include <vector>

#include "octshape/io/atomic_file.h"
#include "octshape/io/error.h"

namespace octshape::app {

void save_png(const cv::Mat& img, const std::string& path) {
    std::vector<uchar> buf;
    if (!cv::imencode(".png", img, buf)) throw OutputError(path, "PNG encoding failed");
    io::write_text_atomically(
        path, std::string_view(reinterpret_cast<const char*>(buf.data()), buf.size()));
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
