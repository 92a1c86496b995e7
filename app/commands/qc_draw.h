#pragma once
// Drawing helpers shared by the QC pictures of the macula and the optic nerve head.

#include <opencv2/core.hpp>
#include <string>

namespace octshape::app {

// Encodes `img` as PNG and writes it atomically to `path` (OutputError on failure).
void save_png(const cv::Mat& img, const std::string& path);

// snprintf of one number, e.g. printf_number("CFT %.1f um", 231.4).
[[nodiscard]] std::string printf_number(const char* format, double value);

// Text in colour `c` with a black outline, readable on any background.
void outlined_text(cv::Mat& img, const std::string& s, cv::Point p, double scale, cv::Scalar c);

}  // namespace octshape::app
