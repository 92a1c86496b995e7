#include "octshape/qc/onh.h"

#include "octshape/qc/onh_radial.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <numbers>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <utility>
#include <vector>

#include "octshape/qc/draw.h"
#include "octshape/qc/fundus.h"
#include "octshape/qc/names.h"
#include "octshape/error.h"
#include "octshape/mesh/section.h"

namespace octshape::qc {
namespace {

using namespace onh_colours;  // octshape/qc/onh_radial.h
const cv::Scalar& kFilled = palette::kCyan;
const cv::Scalar& kInplane = palette::kDeepBlue;  // radial scans: the in-plane MRW

// Height above the RPE of the topmost ILM face over each grid cell (retina::onh_enface_heights),
// in the fundus frame (fundus.h): superior up, whichever way the B-scans ran.
cv::Mat enface_picture(const io::Scan& scan, const retina::OnhResult& r,
                       const retina::OnhParams& p, const std::string& title) {
    const retina::GridSurface& g = r.rpe;
    const int cw = g.cols - 1;
    const int ch = g.rows - 1;
    const FundusFrame ff = fundus_frame(scan, cw * g.dx_mm, ch * g.dy_mm);
    // The cells in the fundus frame: fw x fh of them; cell (a, b) of the grid at column fa and
    // row fh - 1 - fb (row 0 at the top = superior).
    const int fw = ff.keeps_axes() ? cw : ch;
    const int fh = ff.keeps_axes() ? ch : cw;
    const CellLayers cells = onh_cell_layers(r, cv::Size(fw, fh), [&](int a, int b) {
        const auto [fa, fb] = ff.fundus_cell(a, b, cw, ch);
        return cv::Point(fa, fh - 1 - fb);
    });
    const double lo = cells.lo;
    const double hi = cells.hi;
    const int W = 800;
    const double ppm = W / ff.width_mm;
    const int H = std::max(40, static_cast<int>(std::lround(ff.height_mm * ppm)));
    cv::Mat big;
    cv::resize(cells.grey, big, cv::Size(W, H), 0, 0, cv::INTER_NEAREST);
    cv::Mat img;
    cv::applyColorMap(big, img, cv::COLORMAP_VIRIDIS);
    auto px = [&](double x, double y) {
        const Eigen::Vector2d f = ff.to_fundus({x, y});
        return cv::Point(static_cast<int>(std::lround(f.x() * ppm)),
                         static_cast<int>(std::lround(H - 1 - f.y() * ppm)));
    };
    cv::Mat cup_big;
    // Cup outline: the boundary of the cells below the RPE, in black.
    cv::resize(cells.cup, cup_big, cv::Size(W, H), 0, 0, cv::INTER_NEAREST);
    std::vector<std::vector<cv::Point>> contours;
    cv::findContours(cup_big, contours, cv::RETR_EXTERNAL, cv::CHAIN_APPROX_SIMPLE);
    cv::drawContours(img, contours, -1, cv::Scalar(0, 0, 0), 2, cv::LINE_AA);
    const Eigen::Vector2d c = r.ellipse.centre_mm;
    cv::circle(img, px(c.x(), c.y()), static_cast<int>(std::lround(p.disc_radius_mm * ppm)), kDisc,
               2, cv::LINE_AA);
    std::vector<cv::Point> poly;
    for (const auto& q : r.ellipse.points_mm) poly.push_back(px(q.x(), q.y()));
    cv::polylines(img, poly, true, kEllipse, 2, cv::LINE_AA);
    for (const auto& m : r.bmo_measured) cv::circle(img, px(m.mm.x(), m.mm.y()), 3, kBmo, -1);
    cv::drawMarker(img, px(c.x(), c.y()), cv::Scalar(255, 0, 255), cv::MARKER_CROSS, 18, 2);
    // N, S, T, I from the grid -> anatomical map (columns: images of +x and +y).
    const Eigen::Matrix2d inv = r.grid_to_anatomical.inverse();
    const Eigen::Vector2d nasal = inv.col(0).normalized();
    const Eigen::Vector2d sup = inv.col(1).normalized();
    const double lr = p.disc_radius_mm + 0.12;
    for (const auto& [dir, label] : {std::pair{nasal, "N"}, std::pair{sup, "S"},
                                     std::pair{Eigen::Vector2d(-nasal), "T"},
                                     std::pair{Eigen::Vector2d(-sup), "I"}}) {
        outlined_text(img, label, px(c.x() + lr * dir.x(), c.y() + lr * dir.y()) + cv::Point(-7, 7),
                      0.7, palette::kWhite);
    }
    scale_bar(img, {14, H - 16}, ppm, palette::kWhite);
    const int bar_w = 140;
    cv::Mat out(34 + H + 40 + 96, W + bar_w, CV_8UC3, palette::kPanel);
    outlined_text(out, title, {8, 24}, 0.55, palette::kWhite);
    img.copyTo(out(cv::Rect(0, 34 + 30, W, H)));
    colour_bar(out, cv::Rect(W + 18, 34 + 36, 22, H - 12), lo, hi, cv::COLORMAP_VIRIDIS,
               "ILM above RPE (um)", 1e3, "%.0f");
    const int y0 = 34 + 30 + H + 26;
    const int end = draw_legend(
        out, {8, y0},
        {{LegendItem::kDot, kBmo, "BMO points"},
         {LegendItem::kLine, kEllipse, "BMO ellipse"},
         {LegendItem::kLine, kDisc, printf_number("disc, %.1f mm radius", p.disc_radius_mm)},
         {LegendItem::kLine, cv::Scalar(0, 0, 0), "cup edge (ILM at RPE height)"},
         {LegendItem::kCross, cv::Scalar(255, 0, 255), "BMO centre"}},
        0.45, palette::kText, W + bar_w - 8);
    plain_text(out, "ILM surface: " + r.ilm_source, {8, end + 14}, 0.45,
               palette::kText);
    plain_text(out,
               "BMO area " + printf_number("%.3f mm2", r.ellipse.area_mm2) + "   cup volume " +
                   printf_number("%.3f mm3", r.cup_volume_mm3) + "   CONHT " +
                   printf_number("%.0f um", r.conht_mm * 1e3),
               {8, end + 40}, 0.45, palette::kText);
    return out;
}

cv::Mat bscan_panel(const io::Scan& scan, const retina::OnhResult& r, int b) {
    const int W = scan.meta.size_x;
    const int H = scan.meta.size_z;
    const io::BScan& bs = scan.bscans[static_cast<std::size_t>(b)];
    const cv::Mat grey = bscan_grey(bs, W, H);
    cv::Mat img;
    cv::cvtColor(grey, img, cv::COLOR_GRAY2BGR);
    const double dx = scan.meta.scale_x_mm;
    const double dz = scan.meta.scale_z_mm;
    auto px = [&](double x_mm, double z_mm) {
        return cv::Point(static_cast<int>(std::lround(x_mm / dx)),
                         static_cast<int>(std::lround(-z_mm / dz)));
    };
    auto draw_line = [&](int k, const cv::Scalar& col) {
        if (!bs.has_line(k)) return;
        const auto& line = bs.seg[static_cast<std::size_t>(k)];
        for (std::size_t a = 0; a + 1 < line.size(); ++a) {
            if (!io::is_valid(line[a]) || !io::is_valid(line[a + 1])) continue;
            cv::line(img, cv::Point(static_cast<int>(a), static_cast<int>(std::lround(line[a]))),
                     cv::Point(static_cast<int>(a + 1), static_cast<int>(std::lround(line[a + 1]))),
                     col, 1, cv::LINE_AA);
        }
    };
    draw_line(static_cast<int>(io::Layer::kBM), kBm);
    draw_line(static_cast<int>(io::Layer::kILM), kDeviceIlm);
    const retina::GridSurface& g = r.rpe;
    for (int a = 0; a < g.cols; ++a) {
        const auto i = static_cast<std::size_t>(b) * static_cast<std::size_t>(g.cols) +
                       static_cast<std::size_t>(a);
        if (g.filled[i]) cv::circle(img, px(a * g.dx_mm, g.z[i]), 0, kFilled, -1);
    }
    // The ILM used: the mesh cut by the B-scan's plane (nudged off the grid lines).
    for (const auto& s :
         mesh::plane_section(r.ilm_V, r.ilm_F, Eigen::Vector3d::UnitY(), b * g.dy_mm + 1e-7)) {
        cv::line(img, px(s.a.x(), s.a.z()), px(s.b.x(), s.b.z()), kUsedIlm, 1, cv::LINE_AA);
    }
    for (const auto& m : r.bmo_measured) {
        if (m.bscan == b) cv::circle(img, px(m.mm.x(), m.mm.z()), 4, kDisc, 1, cv::LINE_AA);
    }
    for (std::size_t i = 0; i < r.ellipse.points_mm.size(); ++i) {
        const Eigen::Vector3d& p = r.ellipse.points_mm[i];
        if (std::fabs(p.y() - b * g.dy_mm) > 0.5 * g.dy_mm) continue;
        const Eigen::Vector3d& q = r.mrw_points_mm[i];
        cv::line(img, px(p.x(), p.z()), px(q.x(), q.z()), kMrw, 1, cv::LINE_AA);
    }
    // What the registrations did on a line of its own under the title: a panel of a small
    // volume is too narrow for both on one line.
    outlined_text(img, "B-scan " + std::to_string(b) + " of 0-" + std::to_string(scan.num_bscans() - 1),
                  {6, 18}, 0.5, palette::kWhite);
    const std::string moved = registration_title(r, b);
    if (moved.size() > 2) outlined_text(img, moved.substr(2), {6, 36}, 0.5, palette::kWhite);
    scale_bar(img, {10, H - 14}, 1.0 / dx, palette::kWhite);
    return img;
}

cv::Mat bscans_picture(const io::Scan& scan, const retina::OnhResult& r,
                       const std::string& title) {
    const double dy = r.rpe.dy_mm;
    const double cy = r.ellipse.centre_mm.y();
    const double th = r.ellipse.orientation_deg * std::numbers::pi / 180.0;
    const double a = r.ellipse.semi_major_mm;
    const double bb = r.ellipse.semi_minor_mm;
    const double half_y =
        std::sqrt(a * a * std::sin(th) * std::sin(th) + bb * bb * std::cos(th) * std::cos(th));
    std::vector<int> picks;
    for (const double off : {-0.5 * half_y, 0.0, 0.5 * half_y}) {
        picks.push_back(
            std::clamp(static_cast<int>(std::lround((cy + off) / dy)), 0, scan.num_bscans() - 1));
    }
    std::vector<cv::Mat> panels;
    for (const int b : picks) panels.push_back(bscan_panel(scan, r, b));
    cv::Mat row;
    cv::hconcat(panels, row);
    cv::Mat out(34 + row.rows + 70, row.cols, CV_8UC3, palette::kPanel);
    outlined_text(out, title, {8, 24}, 0.55, palette::kWhite);
    row.copyTo(out(cv::Rect(0, 34, row.cols, row.rows)));
    draw_legend(out, {8, 34 + row.rows + 24},
                {{LegendItem::kLine, kDeviceIlm, "device ILM"},
                 {LegendItem::kLine, kUsedIlm, "ILM used (" + r.ilm_source + ")"},
                 {LegendItem::kLine, kBm, "device BM"},
                 {LegendItem::kDot, kFilled, "filled RPE"},
                 {LegendItem::kRing, kDisc, "BMO points"},
                 {LegendItem::kLine, kMrw, "MRW vectors"}},
                0.45, palette::kText, row.cols - 8);
    plain_text(out,
               "each B-scan " + printf_number("%.2f mm wide", scan.meta.size_x * scan.meta.scale_x_mm) +
                   printf_number(", %.2f mm deep (depth drawn stretched)",
                                 scan.meta.size_z * scan.meta.scale_z_mm),
               {8, 34 + row.rows + 56}, 0.45, palette::kText);
    return out;
}

}  // namespace

cv::Mat onh_mrw_picture(const retina::OnhResult& r, const std::string& title) {
    const int W = 930;
    const int extra = r.radial ? 24 : 0;  // a second legend row
    const int H = 420 + extra;
    cv::Mat img(H, W, CV_8UC3, palette::kWhite);
    cv::rectangle(img, cv::Rect(0, 0, W, 34), palette::kPanel, -1);
    outlined_text(img, title, {8, 24}, 0.55, palette::kWhite);
    double hi = 0.05;
    for (const double m : r.mrw_mm) {
        if (std::isfinite(m)) hi = std::max(hi, m);
    }
    for (const auto& m : r.mrw_inplane) hi = std::max(hi, m.mrw_mm);
    hi *= 1.1;
    Axes a;
    a.plot = cv::Rect(80, 84 + extra, W - 110, H - 174 - extra);
    a.x0 = 0.0;
    a.x1 = 360.0;
    a.y0 = 0.0;
    a.y1 = hi;
    draw_axes(img, a, "", "MRW (um)", "%.0f", "%.0f", 1e3, 0.42, 0, 5);
    // x ticks every 30 degrees, and the anatomical directions under 0, 90, 180, 270, 360.
    const cv::Scalar ink(60, 60, 60);
    for (int k = 0; k <= 12; ++k) {
        const cv::Point q = a.px(30.0 * k, 0.0);
        cv::line(img, {q.x, a.plot.y}, {q.x, a.plot.y + a.plot.height}, cv::Scalar(225, 225, 225), 1);
        cv::line(img, q, q + cv::Point(0, 4), ink, 1);
        const std::string deg = std::to_string(30 * k);
        plain_text(img, deg, q + cv::Point(-4 * static_cast<int>(deg.size()), 18), 0.42, ink);
        if (k % 3 == 0) {
            static const char* kDir[] = {"N", "S", "T", "I", "N"};
            outlined_text(img, kDir[k / 3], q + cv::Point(-6, 42), 0.7, palette::kWhite);
        }
    }
    cv::rectangle(img, a.plot, ink, 1);
    plain_text(img, "anatomical angle (deg): N nasal, S superior, T temporal, I inferior",
               {a.plot.x + 180, a.plot.y + a.plot.height + 62}, 0.42, ink);
    for (int k = 0; k < 12; ++k) {
        const double lo = std::max(0.0, 30.0 * k - 15.0);
        const double up = std::min(360.0, 30.0 * k + 15.0);
        const double m = r.mrw_sector_mm[static_cast<std::size_t>(k)];
        if (!std::isnan(m)) {
            cv::line(img, a.px(lo, m), a.px(up, m), cv::Scalar(40, 40, 200), 2);
            if (k == 0) cv::line(img, a.px(345.0, m), a.px(360.0, m), cv::Scalar(40, 40, 200), 2);
        }
    }
    for (std::size_t i = 0; i < r.mrw_mm.size(); ++i) {
        cv::circle(img, a.px(r.bmo_anatomical_deg[i], r.mrw_mm[i]), 2, kMrw, -1);
    }
    std::vector<LegendItem> legend{
        {LegendItem::kDot, kMrw,
         r.radial ? "3-D MRW at each ellipse point" : "MRW at each BMO point"},
        {LegendItem::kLine, cv::Scalar(40, 40, 200), "30-degree sector means"}};
    std::string means = "mean " + printf_number("%.0f um", r.mrw_mean_mm * 1e3);
    if (r.radial) {
        // The in-plane MRW (the device's definition) at each measured BMO point, numbered by
        // its B-scan (the contact sheet's panels), and its sector means.
        for (int k = 0; k < 12; ++k) {
            const double m = r.mrw_inplane_sector_mm[static_cast<std::size_t>(k)];
            if (std::isnan(m)) continue;
            const double lo = std::max(0.0, 30.0 * k - 15.0);
            const double up = std::min(360.0, 30.0 * k + 15.0);
            cv::line(img, a.px(lo, m), a.px(up, m), kInplane, 1);
            if (k == 0) cv::line(img, a.px(345.0, m), a.px(360.0, m), kInplane, 1);
        }
        for (const auto& m : r.mrw_inplane) {
            const cv::Point q = a.px(m.anatomical_deg, m.mrw_mm);
            cv::circle(img, q, 4, kInplane, 1, cv::LINE_AA);
            plain_text(img, std::to_string(m.bscan), q + cv::Point(5, -5), 0.33, kInplane);
        }
        legend.push_back({LegendItem::kRing, kInplane, "in-plane MRW (B-scan number, from 0)"});
        legend.push_back({LegendItem::kLine, kInplane, "its sector means"});
        means = "3-D " + means + printf_number(", in-plane %.0f um", r.mrw_inplane_mean_mm * 1e3);
    }
    int base = 0;
    const int means_w =
        cv::getTextSize(means, cv::FONT_HERSHEY_SIMPLEX, 0.45, 1, &base).width;
    // A volume's as before; a radial scan's longer text right-aligned.
    draw_legend(img, {a.plot.x, 56}, legend, 0.45, cv::Scalar(20, 20, 20),
                r.radial ? W - means_w - 30 : W - 10);
    plain_text(img, means, {r.radial ? W - 10 - means_w : W - 150, 56}, 0.45,
               cv::Scalar(20, 20, 20));
    return img;
}

void write_onh_qc(const io::Scan& scan,
                  const retina::OnhResult& r,
                  const retina::OnhParams& p,
                  const std::string& dir,
                  const std::string& stem) {
    const std::filesystem::path d = qc_directory(dir);
    const std::string title = scan_title(scan.meta, scan.num_bscans());
    // A radial scan's pictures under the volume's names (the gallery and the cohort's resume
    // know them): its lines on the scanned circle, and every radial B-scan.
    const std::string enface = (d / picture_name(stem, kind::kEnface)).string();
    const std::string bscans = (d / picture_name(stem, kind::kBscans)).string();
    // Every picture is drawn before any is written: a drawing error leaves no picture behind.
    const cv::Mat e =
        r.radial ? radial_enface_picture(scan, r, p, title) : enface_picture(scan, r, p, title);
    const cv::Mat b =
        r.radial ? radial_bscans_picture(scan, r, title) : bscans_picture(scan, r, title);
    const cv::Mat m = onh_mrw_picture(r, title);
    save_png(e, enface);
    save_png(b, bscans);
    save_png(m, (d / picture_name(stem, kind::kMrw)).string());
}

}  // namespace octshape::qc
