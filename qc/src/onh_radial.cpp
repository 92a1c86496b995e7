#include "octshape/qc/onh_radial.h"

#include <algorithm>
#include <array>
#include <climits>
#include <cmath>
#include <limits>
#include <opencv2/imgproc.hpp>
#include <utility>
#include <vector>

#include "octshape/mesh/section.h"
#include "octshape/qc/draw.h"

namespace octshape::qc {
namespace {

// The ONH pictures' colours (octshape/qc/onh_radial.h), and those of what only a radial scan has.
using namespace onh_colours;
const cv::Scalar& kCrossing = palette::kCyan;
const cv::Scalar kLine(200, 200, 200);
const cv::Scalar kNotScanned(60, 60, 60);

cv::Point round_pt(double x, double y) {
    return {static_cast<int>(std::lround(x)), static_cast<int>(std::lround(y))};
}

// The ILM mesh cut by the vertical plane of line `line`: segments of (A-scan, depth px).
std::vector<std::array<Eigen::Vector2d, 2>> line_cut(const io::Scan& scan,
                                                     const retina::RadialGeometry& geo,
                                                     const retina::OnhResult& r,
                                                     int line) {
    const int nx = scan.meta.size_x;
    const Eigen::Vector2d o = r.radial_crossing_mm + geo.ascan_mm(line, 0.0, nx);
    const Eigen::Vector2d u = geo.direction(line);
    const Eigen::Vector2d n(-u.y(), u.x());
    const double ds = geo.lines[static_cast<std::size_t>(line)].length_mm / (nx - 1);
    const double dz = scan.meta.scale_z_mm;
    // The line's vertical plane n . (x, y) = n . o, moved off the vertices (a line along a grid
    // row or column passes through them).
    std::vector<std::array<Eigen::Vector2d, 2>> segs;
    for (const mesh::SectionSegment& sg : mesh::plane_section(r.ilm_V, r.ilm_F, {n.x(), n.y(), 0.0}, n.dot(o) - 1e-9)) {
        auto at = [&](const Eigen::Vector3d& p) -> Eigen::Vector2d {
            return {(p.head<2>() - o).dot(u) / ds, -p.z() / dz};
        };
        segs.push_back({at(sg.a), at(sg.b)});
    }
    return segs;
}

// Valid values of a segmentation line of a B-scan, or nullptr.
const std::vector<float>* layer_line(const io::BScan& bs, io::Layer layer) {
    const int k = static_cast<int>(layer);
    return bs.has_line(k) ? &bs.seg[static_cast<std::size_t>(k)] : nullptr;
}

}  // namespace

cv::Point RadialEnfaceLayout::px(double x_mm, double y_mm) const {
    return round_pt(margin + x_mm * ppm, top + margin + (map_height - 1) - y_mm * ppm);
}

cv::Point RadialSheetLayout::origin(int line) const {
    return {(line % cols) * (panel_w + gap), top + (line / cols) * (panel_h + gap)};
}

cv::Point RadialSheetLayout::px(int line, double ascan, double depth_px) const {
    const cv::Point o = origin(line);
    // Source pixel i covers [i sx, (i + 1) sx) of the panel: its centre is at (i + 0.5) sx.
    return round_pt(o.x + (ascan + 0.5) * sx() - 0.5, o.y + (depth_px - z0 + 0.5) * sz() - 0.5);
}

CellLayers onh_cell_layers(const retina::OnhResult& r,
                           cv::Size size,
                           const std::function<cv::Point(int, int)>& place) {
    const retina::OnhEnfaceGrid grid = retina::onh_enface_heights(r);
    CellLayers out;
    out.cols = grid.cols;
    out.rows = grid.rows;
    for (const double v : grid.height_mm) {
        if (std::isnan(v)) continue;
        out.lo = std::min(out.lo, v);
        out.hi = std::max(out.hi, v);
    }
    if (size.empty()) size = cv::Size(grid.cols, grid.rows);
    out.grey = cv::Mat(size, CV_8UC1, cv::Scalar(0));
    out.cup = cv::Mat(size, CV_8UC1, cv::Scalar(0));
    out.none = cv::Mat(size, CV_8UC1, cv::Scalar(0));
    for (int b = 0; b < grid.rows; ++b) {
        for (int a = 0; a < grid.cols; ++a) {
            const cv::Point at = place ? place(a, b) : cv::Point(a, grid.rows - 1 - b);
            const double v = grid.at(a, b);
            if (std::isnan(v)) {
                out.none.at<uchar>(at) = 255;
                continue;
            }
            out.grey.at<uchar>(at) =
                static_cast<uchar>(std::lround(255 * ((v - out.lo) / (out.hi - out.lo))));
            if (v < 0.0) out.cup.at<uchar>(at) = 255;
        }
    }
    return out;
}

double radial_ascan_of(const retina::RadialGeometry& geo,
                       const retina::OnhResult& r,
                       int line,
                       int size_x,
                       const Eigen::Vector2d& xy) {
    const Eigen::Vector2d o = r.radial_crossing_mm + geo.ascan_mm(line, 0.0, size_x);
    const double ds = geo.lines[static_cast<std::size_t>(line)].length_mm / (size_x - 1);
    return (xy - o).dot(geo.direction(line)) / ds;
}

cv::Mat radial_enface_picture(const io::Scan& scan,
                              const retina::OnhResult& r,
                              const retina::OnhParams& p,
                              const std::string& title,
                              RadialEnfaceLayout* layout_out) {
    const retina::RadialGeometry geo = retina::radial_geometry(scan);
    const int nx = scan.meta.size_x;
    const retina::GridSurface& g = r.rpe;
    // Image row 0 at the top = largest grid y (superior).
    const CellLayers cells = onh_cell_layers(r);
    const int cw = cells.cols;
    const int ch = cells.rows;
    const double lo = cells.lo;
    const double hi = cells.hi;
    RadialEnfaceLayout L;
    const int W = 760;
    L.ppm = W / (cw * g.dx_mm);
    L.map_height = std::max(40, static_cast<int>(std::lround(ch * g.dy_mm * L.ppm)));
    L.margin = 40;
    L.top = 34;
    const int H = L.map_height;
    cv::Mat big;
    cv::Mat none_big;
    cv::Mat cup_big;
    cv::resize(cells.grey, big, cv::Size(W, H), 0, 0, cv::INTER_NEAREST);
    cv::resize(cells.none, none_big, cv::Size(W, H), 0, 0, cv::INTER_NEAREST);
    cv::resize(cells.cup, cup_big, cv::Size(W, H), 0, 0, cv::INTER_NEAREST);
    cv::Mat map;
    cv::applyColorMap(big, map, cv::COLORMAP_VIRIDIS);
    map.setTo(kNotScanned, none_big);
    const int bar_w = 140;
    const int canvas_w = W + 2 * L.margin;
    cv::Mat out(L.top + H + 2 * L.margin + 110, canvas_w + bar_w, CV_8UC3, palette::kPanel);
    map.copyTo(out(cv::Rect(L.margin, L.top + L.margin, W, H)));
    std::vector<std::vector<cv::Point>> contours;
    cv::findContours(cup_big, contours, cv::RETR_EXTERNAL, cv::CHAIN_APPROX_SIMPLE);
    cv::drawContours(out, contours, -1, cv::Scalar(0, 0, 0), 2, cv::LINE_AA, cv::noArray(), INT_MAX,
                     cv::Point(L.margin, L.top + L.margin));
    // The lines where they were scanned (Start -> End on the SLO), numbered at their End.
    for (int k = 0; k < static_cast<int>(geo.lines.size()); ++k) {
        const Eigen::Vector2d s = r.radial_crossing_mm + geo.ascan_mm(k, 0.0, nx);
        const Eigen::Vector2d e = r.radial_crossing_mm + geo.ascan_mm(k, nx - 1.0, nx);
        cv::line(out, L.px(s.x(), s.y()), L.px(e.x(), e.y()), kLine, 1, cv::LINE_8);
        const Eigen::Vector2d u = geo.direction(k);
        const cv::Point q = L.px(e.x(), e.y()) + round_pt(16.0 * u.x() - 6.0, -16.0 * u.y() + 5.0);
        outlined_text(out, std::to_string(k), q, 0.4, kLine);
    }
    const Eigen::Vector2d c = r.ellipse.centre_mm;
    cv::circle(out, L.px(c.x(), c.y()), static_cast<int>(std::lround(p.disc_radius_mm * L.ppm)),
               kDisc, 2, cv::LINE_AA);
    std::vector<cv::Point> poly;
    for (const auto& q : r.ellipse.points_mm) poly.push_back(L.px(q.x(), q.y()));
    cv::polylines(out, poly, true, kEllipse, 2, cv::LINE_AA);
    const Eigen::Vector2d x0 = r.radial_crossing_mm;
    cv::drawMarker(out, L.px(x0.x(), x0.y()), kCrossing, cv::MARKER_TILTED_CROSS, 14, 2);
    cv::drawMarker(out, L.px(c.x(), c.y()), palette::kMagenta, cv::MARKER_CROSS, 18, 2);
    // Last, unsmoothed: nothing covers a BMO point (the tests find them at their pixels).
    for (const auto& m : r.bmo_measured) cv::circle(out, L.px(m.mm.x(), m.mm.y()), 3, kBmo, -1);
    // N, S, T, I at the edge of the scanned circle, from the grid -> anatomical map.
    const Eigen::Matrix2d inv = r.grid_to_anatomical.inverse();
    const Eigen::Vector2d nasal = inv.col(0).normalized();
    const Eigen::Vector2d sup = inv.col(1).normalized();
    const double lr = 0.8 * r.radial_scanned_radius_mm;
    for (const auto& [dir, label] : {std::pair{nasal, "N"}, std::pair{sup, "S"},
                                     std::pair{Eigen::Vector2d(-nasal), "T"},
                                     std::pair{Eigen::Vector2d(-sup), "I"}}) {
        outlined_text(out, label,
                      L.px(x0.x() + lr * dir.x(), x0.y() + lr * dir.y()) + cv::Point(-7, 7), 0.7,
                      palette::kWhite);
    }
    scale_bar(out, {L.margin + 14, L.top + L.margin + H - 16}, L.ppm, palette::kWhite);
    outlined_text(out, title, {8, 24}, 0.55, palette::kWhite);
    colour_bar(out, cv::Rect(canvas_w + 18, L.top + L.margin + 6, 22, H - 12), lo, hi,
               cv::COLORMAP_VIRIDIS, "ILM above RPE (um)", 1e3, "%.0f");
    const int y0 = L.top + H + 2 * L.margin + 16;
    const int end = draw_legend(
        out, {8, y0},
        {{LegendItem::kLine, kLine, "radial lines (B-scan number from 0 at the End)"},
         {LegendItem::kTiltedCross, kCrossing, "line crossing"},
         {LegendItem::kDot, kBmo, "BMO points (two per line)"},
         {LegendItem::kLine, kEllipse, "BMO ellipse"},
         {LegendItem::kLine, kDisc, printf_number("disc, %.1f mm radius", p.disc_radius_mm)},
         {LegendItem::kLine, cv::Scalar(0, 0, 0), "cup edge (ILM at RPE height)"},
         {LegendItem::kCross, palette::kMagenta, "BMO centre"},
         {LegendItem::kDot, kNotScanned, "outside the scanned circle"}},
        0.45, palette::kText, canvas_w + bar_w - 8);
    plain_text(
        out,
        "ILM surface: " + r.ilm_source + ", interpolated between the lines" +
            printf_number("; lines miss the crossing by <= %.0f um", r.radial_max_miss_mm * 1e3),
        {8, end + 14}, 0.45, palette::kText);
    plain_text(out,
               "BMO area " + printf_number("%.3f mm2", r.ellipse.area_mm2) + "   cup volume " +
                   printf_number("%.3f mm3", r.cup_volume_mm3) + "   CONHT " +
                   printf_number("%.0f um", r.conht_mm * 1e3),
               {8, end + 40}, 0.45, palette::kText);
    if (layout_out != nullptr) *layout_out = L;
    return out;
}

cv::Mat radial_bscans_picture(const io::Scan& scan,
                              const retina::OnhResult& r,
                              const std::string& title,
                              RadialSheetLayout* layout_out) {
    const retina::RadialGeometry geo = retina::radial_geometry(scan);
    const int nl = static_cast<int>(geo.lines.size());
    const int nx = scan.meta.size_x;
    const int nz = scan.meta.size_z;
    const double dz = scan.meta.scale_z_mm;
    std::vector<std::vector<std::array<Eigen::Vector2d, 2>>> cuts;
    // The depth rows shown: every device ILM and BM value, the used ILM and the BMO points, with
    // a margin of a fifth of that span (at least 10 rows), the same for every panel.
    double top = std::numeric_limits<double>::infinity();
    double bottom = -std::numeric_limits<double>::infinity();
    auto cover = [&](double z) {
        if (!std::isfinite(z)) return;
        top = std::min(top, z);
        bottom = std::max(bottom, z);
    };
    for (int k = 0; k < nl; ++k) {
        const io::BScan& bs = scan.bscans[static_cast<std::size_t>(k)];
        for (const io::Layer layer : {io::Layer::kILM, io::Layer::kBM}) {
            if (const auto* line = layer_line(bs, layer)) {
                for (const float v : *line) {
                    if (io::is_valid(v)) cover(v);
                }
            }
        }
        cuts.push_back(line_cut(scan, geo, r, k));
        for (const auto& s : cuts.back()) {
            cover(s[0].y());
            cover(s[1].y());
        }
    }
    for (const auto& m : r.bmo_measured) cover(-m.mm.z() / dz);
    RadialSheetLayout L;
    L.lines = nl;
    L.cols = nl <= 4 ? nl : (nl <= 12 ? 4 : 6);
    L.rows = (nl + L.cols - 1) / L.cols;
    L.size_x = nx;
    if (std::isfinite(top)) {
        const double m = std::max(10.0, 0.2 * (bottom - top));
        L.z0 = std::clamp(static_cast<int>(std::floor(top - m)), 0, nz - 1);
        L.z1 = std::clamp(static_cast<int>(std::ceil(bottom + m)) + 1, L.z0 + 1, nz);
    } else {
        L.z0 = 0;
        L.z1 = nz;
    }
    // 400 px per line (a 6 mm line: 15 um per pixel) and 240 px of depth (stretched): a BMO end
    // and its MRW segment are resolved in every panel of a 24-line sheet (2400 px wide).
    L.panel_w = 400;
    L.panel_h = 240;
    L.gap = 6;
    L.top = 34;
    const int sheet_w = L.cols * L.panel_w + (L.cols - 1) * L.gap;
    const int sheet_h = L.rows * L.panel_h + (L.rows - 1) * L.gap;
    cv::Mat out(L.top + sheet_h + 84, sheet_w, CV_8UC3, palette::kPanel);
    outlined_text(out, title, {8, 24}, 0.55, palette::kWhite);
    for (int k = 0; k < nl; ++k) {
        const io::BScan& bs = scan.bscans[static_cast<std::size_t>(k)];
        const cv::Mat grey = bscan_grey(bs, nx, nz)(cv::Range(L.z0, L.z1), cv::Range::all());
        cv::Mat big;
        cv::resize(grey, big, cv::Size(L.panel_w, L.panel_h), 0, 0, cv::INTER_AREA);
        cv::Mat colour;
        cv::cvtColor(big, colour, cv::COLOR_GRAY2BGR);
        const cv::Rect panel(L.origin(k), cv::Size(L.panel_w, L.panel_h));
        colour.copyTo(out(panel));
        // Drawn on the panel only: nothing spills into a neighbour.
        cv::Mat img = out(panel);
        const cv::Point o = L.origin(k);
        auto at = [&](double a, double z) { return L.px(k, a, z) - o; };
        for (const auto& [layer, col] :
             {std::pair{io::Layer::kBM, kBm}, std::pair{io::Layer::kILM, kDeviceIlm}}) {
            const auto* line = layer_line(bs, layer);
            if (line == nullptr) continue;
            for (std::size_t a = 0; a + 1 < line->size(); ++a) {
                if (!io::is_valid((*line)[a]) || !io::is_valid((*line)[a + 1])) continue;
                cv::line(img, at(static_cast<double>(a), (*line)[a]),
                         at(static_cast<double>(a + 1), (*line)[a + 1]), col, 1, cv::LINE_AA);
            }
        }
        // The ILM the analysis used: its mesh cut by this B-scan's vertical plane.
        for (const auto& s : cuts[static_cast<std::size_t>(k)]) {
            cv::line(img, at(s[0].x(), s[0].y()), at(s[1].x(), s[1].y()), kUsedIlm, 1, cv::LINE_AA);
        }
        for (const auto& m : r.mrw_inplane) {
            if (m.bscan != k) continue;
            const double a0 = radial_ascan_of(geo, r, k, nx, m.bmo_mm.head<2>());
            const double a1 = radial_ascan_of(geo, r, k, nx, m.ilm_mm.head<2>());
            cv::line(img, at(a0, -m.bmo_mm.z() / dz), at(a1, -m.ilm_mm.z() / dz), kMrw, 1,
                     cv::LINE_AA);
        }
        for (const auto& m : r.bmo_measured) {
            if (m.bscan != k) continue;
            const double a = radial_ascan_of(geo, r, k, nx, m.mm.head<2>());
            cv::circle(img, at(a, -m.mm.z() / dz), 5, kDisc, 1, cv::LINE_AA);
        }
        // Which way the line runs: the anatomical angle of its Start (left) and End (right).
        const double ang = geo.lines[static_cast<std::size_t>(k)].angle_deg;
        outlined_text(img, "B-scan " + std::to_string(k) + printf_number(", %.0f deg", ang) +
                               registration_title(r, k),
                      {6, 16}, 0.45, palette::kWhite);
        outlined_text(img, printf_number("%.0f", std::fmod(ang + 180.0, 360.0)), {4, L.panel_h - 8},
                      0.4, palette::kWhite);
        outlined_text(img, printf_number("%.0f", ang), {L.panel_w - 30, L.panel_h - 8}, 0.4,
                      palette::kWhite);
    }
    const int y = L.top + sheet_h + 24;
    draw_legend(out, {8, y},
                {{LegendItem::kLine, kDeviceIlm, "device ILM"},
                 {LegendItem::kLine, kUsedIlm, "ILM used (" + r.ilm_source + " mesh in the plane)"},
                 {LegendItem::kLine, kBm, "device BM"},
                 {LegendItem::kRing, kDisc, "BMO points"},
                 {LegendItem::kLine, kMrw, "in-plane MRW"}},
                0.45, palette::kText, sheet_w - 8);
    plain_text(out,
               "every radial B-scan, numbered from 0, Start at the left (corner numbers: anatomical angle of "
               "each end, deg; 0 nasal, 90 superior); each " +
                   printf_number("%.2f mm wide", geo.mean_length_mm) +
                   printf_number(", %.2f mm deep shown (stretched)", (L.z1 - L.z0) * dz),
               {8, y + 36}, 0.45, palette::kText);
    if (layout_out != nullptr) *layout_out = L;
    return out;
}

}  // namespace octshape::qc
