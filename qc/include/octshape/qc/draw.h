#pragma once
// Drawing helpers shared by the QC pictures of the macula and the optic nerve head: titles,
// axes with ticks, colour bars, scale bars and legends, so that every picture reads alone.

#include <filesystem>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "octshape/io/scan.h"

namespace octshape::qc {

// The one palette of every QC picture (BGR), so that a layer or a kind of mark has the same
// colour in the macula's and the optic nerve head's pictures; each picture names its uses.
namespace palette {
inline const cv::Scalar kRed(40, 40, 230);
inline const cv::Scalar kYellow(0, 220, 255);
inline const cv::Scalar kAmber(0, 200, 255);
inline const cv::Scalar kWhite(255, 255, 255);
inline const cv::Scalar kGreen(60, 200, 60);
inline const cv::Scalar kDarkGreen(60, 180, 60);
inline const cv::Scalar kBlue(230, 150, 40);
inline const cv::Scalar kDeepBlue(220, 120, 30);
inline const cv::Scalar kMagenta(255, 0, 255);
inline const cv::Scalar kPink(230, 60, 230);
inline const cv::Scalar kCyan(230, 230, 0);
inline const cv::Scalar kText(230, 230, 230);
inline const cv::Scalar kPanel(30, 30, 30);
}  // namespace palette

// The folder `dir` of a command's QC pictures, created when absent (OutputError when it
// cannot be).
[[nodiscard]] std::filesystem::path qc_directory(const std::string& dir);

// Encodes `img` as PNG and writes it atomically to `path` (OutputError on failure).
void save_png(const cv::Mat& img, const std::string& path);

// snprintf of one number, e.g. printf_number("CFT %.1f um", 231.4).
[[nodiscard]] std::string printf_number(const char* format, double value);

// What the registrations did to one B-scan, for its title: ", moved 12 um up" (axial, + = up),
// ", moved 9 um left" (lateral, + = towards lower A-scans), both ", moved 12 um up, 9 um left";
// a value under 0.5 um is left out, nothing moved gives "". The ONH and macula pictures alike.
[[nodiscard]] std::string registration_title(double up_um, double left_um);

// Text in colour `c` with a black outline, readable on any background.
void outlined_text(cv::Mat& img, const std::string& s, cv::Point p, double scale, cv::Scalar c);

// Plain text (no outline), FONT_HERSHEY_SIMPLEX, 1 px thick.
void plain_text(cv::Mat& img, const std::string& s, cv::Point p, double scale, cv::Scalar c);

// The picture title: eye, scan pattern and size, e.g. "OD, volume (pattern 3), 25 B-scans x
// 512 A-scans, 6.00 x 6.00 mm". No identifier, date or file name.
[[nodiscard]] std::string scan_title(const io::ScanMeta& meta, int num_bscans);

// The anatomical label of the en-face pictures at anatomical angle `deg` (0 nasal, 90 superior,
// 180 temporal, 270 inferior, both eyes): "N", "S", "T", "I", else nullptr.
[[nodiscard]] const char* anatomical_label(double deg);

// "Nice" tick values (1, 2, 5 x 10^k steps) covering [lo, hi], about `count` of them.
[[nodiscard]] std::vector<double> nice_ticks(double lo, double hi, int count);

// Axes on the rectangle `plot` of `img` for data ranges [x0, x1] × [y0, y1] (y up): a frame,
// ticks with values (printf `xfmt`/`yfmt`, values multiplied by `yscale` for the y labels) and
// the axis labels (units in them).
struct Axes {
    cv::Rect plot;
    double x0 = 0.0, x1 = 1.0, y0 = 0.0, y1 = 1.0;
    [[nodiscard]] cv::Point px(double x, double y) const;
};
void draw_axes(cv::Mat& img, const Axes& a, const std::string& xlabel, const std::string& ylabel,
               const char* xfmt, const char* yfmt, double yscale, double font = 0.4,
               int xticks = 5, int yticks = 4);

// A vertical colour bar (OpenCV colormap `map`, lo at the bottom) at `where`, with ticks and
// labels of the values × `label_scale` (printf `fmt`) and a caption (units) above it.
void colour_bar(cv::Mat& img, cv::Rect where, double lo, double hi, int map,
                const std::string& caption, double label_scale, const char* fmt);

// A B-scan's pixels (size_z rows × size_x columns) for display: v^0.25, clamped to [0, 1],
// as 8-bit grey; black where the device has no data and everywhere when pixels were not read.
[[nodiscard]] cv::Mat bscan_grey(const io::BScan& bs, int size_x, int size_z);

// A 1 mm scale bar, `px_per_mm` long, its left end at `p`, labelled "1 mm".
void scale_bar(cv::Mat& img, cv::Point p, double px_per_mm, cv::Scalar c);

// One legend entry: a line (kLine), a filled dot (kDot), a ring (kRing), a cross (kCross, +)
// or a tilted cross (kTiltedCross, x) of `colour`.
struct LegendItem {
    enum Kind { kLine, kDot, kRing, kCross, kTiltedCross };
    Kind kind = kLine;
    cv::Scalar colour;
    std::string label;
};
// Draws the items left to right from `p` (wrapping at `max_x`); returns the y below them.
int draw_legend(cv::Mat& img, cv::Point p, const std::vector<LegendItem>& items, double font,
                cv::Scalar text, int max_x);

}  // namespace octshape::qc
