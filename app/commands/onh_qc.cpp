#include "commands/onh_qc.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <numbers>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <vector>

#include "commands/qc_draw.h"
#include "octshape/error.h"

namespace octshape::app {
namespace {

const cv::Scalar kEllipse(40, 40, 230);    // red (BGR)
const cv::Scalar kDisc(0, 220, 255);       // yellow
const cv::Scalar kBmo(255, 255, 255);      // white
const cv::Scalar kDeviceIlm(60, 200, 60);  // green
const cv::Scalar kUsedIlm(40, 40, 240);    // red
const cv::Scalar kBm(230, 150, 40);        // blue
const cv::Scalar kFilled(230, 230, 0);     // cyan
const cv::Scalar kMrw(230, 60, 230);       // magenta

// Height above the RPE of the topmost ILM face over each grid cell.
cv::Mat enface_picture(const retina::OnhResult& r, const retina::OnhParams& p) {
    const retina::GridSurface& g = r.rpe;
    const int cw = g.cols - 1;
    const int ch = g.rows - 1;
    std::vector<double> h(static_cast<std::size_t>(cw) * static_cast<std::size_t>(ch),
                          std::numeric_limits<double>::quiet_NaN());
    std::vector<double> top(h.size(), -std::numeric_limits<double>::infinity());
    const mesh::FaceGeometry fg = mesh::face_geometry(r.ilm_V, r.ilm_F);
    for (Eigen::Index f = 0; f < r.ilm_F.rows(); ++f) {
        if (std::isnan(r.face_height_mm(f))) continue;
        const int a = std::clamp(static_cast<int>(fg.centroids(f, 0) / g.dx_mm), 0, cw - 1);
        const int b = std::clamp(static_cast<int>(fg.centroids(f, 1) / g.dy_mm), 0, ch - 1);
        const auto i = static_cast<std::size_t>(b) * static_cast<std::size_t>(cw) +
                       static_cast<std::size_t>(a);
        if (fg.centroids(f, 2) > top[i]) {
            top[i] = fg.centroids(f, 2);
            h[i] = r.face_height_mm(f);
        }
    }
    double lo = 0.0;
    double hi = 0.1;
    for (const double v : h) {
        if (std::isnan(v)) continue;
        lo = std::min(lo, v);
        hi = std::max(hi, v);
    }
    cv::Mat grey(ch, cw, CV_8UC1, cv::Scalar(0));
    for (int b = 0; b < ch; ++b) {
        for (int a = 0; a < cw; ++a) {
            const double v = h[static_cast<std::size_t>(b) * static_cast<std::size_t>(cw) +
                               static_cast<std::size_t>(a)];
            const double u = std::isnan(v) ? 0.0 : (v - lo) / (hi - lo);
            // Image row 0 at the top = largest grid y.
            grey.at<uchar>(ch - 1 - b, a) = static_cast<uchar>(std::lround(255 * u));
        }
    }
    const double width_mm = cw * g.dx_mm;
    const double height_mm = ch * g.dy_mm;
    const int W = 800;
    const double ppm = W / width_mm;
    const int H = std::max(40, static_cast<int>(std::lround(height_mm * ppm)));
    cv::Mat big;
    cv::resize(grey, big, cv::Size(W, H), 0, 0, cv::INTER_NEAREST);
    cv::Mat img;
    cv::applyColorMap(big, img, cv::COLORMAP_VIRIDIS);
    auto px = [&](double x, double y) {
        return cv::Point(static_cast<int>(std::lround(x * ppm)),
                         static_cast<int>(std::lround(H - 1 - y * ppm)));
    };
    // Cup outline: the boundary of the cells below the RPE, in black.
    cv::Mat cup(ch, cw, CV_8UC1, cv::Scalar(0));
    for (int b = 0; b < ch; ++b) {
        for (int a = 0; a < cw; ++a) {
            const double v = h[static_cast<std::size_t>(b) * static_cast<std::size_t>(cw) +
                               static_cast<std::size_t>(a)];
            if (v < 0.0) cup.at<uchar>(ch - 1 - b, a) = 255;
        }
    }
    cv::Mat cup_big;
    cv::resize(cup, cup_big, cv::Size(W, H), 0, 0, cv::INTER_NEAREST);
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
    // N and S labels from the grid -> anatomical map (columns: images of +x and +y).
    const Eigen::Matrix2d inv = r.grid_to_anatomical.inverse();
    const Eigen::Vector2d nasal = inv.col(0).normalized();
    const Eigen::Vector2d sup = inv.col(1).normalized();
    const double lr = p.disc_radius_mm + 0.12;
    outlined_text(img, "N", px(c.x() + lr * nasal.x(), c.y() + lr * nasal.y()) + cv::Point(-7, 7),
                  0.7, cv::Scalar(255, 255, 255));
    outlined_text(img, "S", px(c.x() + lr * sup.x(), c.y() + lr * sup.y()) + cv::Point(-7, 7), 0.7,
                  cv::Scalar(255, 255, 255));
    cv::Mat out(H + 70, W, CV_8UC3, cv::Scalar(30, 30, 30));
    img.copyTo(out(cv::Rect(0, 0, W, H)));
    outlined_text(out,
                  "ILM height above RPE " + printf_number("%.2f", lo) + " (dark) - " +
                      printf_number("%.2f", hi) +
                      " mm (yellow); black line: cup edge (h = 0); ILM: " + r.ilm_source,
                  {8, H + 22}, 0.5, cv::Scalar(230, 230, 230));
    outlined_text(out, "BMO points", {8, H + 52}, 0.5, kBmo);
    outlined_text(out, "ellipse", {110, H + 52}, 0.5, kEllipse);
    outlined_text(out, printf_number("%.1f mm disc", p.disc_radius_mm), {185, H + 52}, 0.5, kDisc);
    outlined_text(out,
                  "A_bmo " + printf_number("%.3f mm2", r.ellipse.area_mm2) + "  V_cup " +
                      printf_number("%.3f mm3", r.cup_volume_mm3) + "  CONHT " +
                      printf_number("%.3f mm", r.conht_mm),
                  {300, H + 52}, 0.5, cv::Scalar(230, 230, 230));
    return out;
}

// Segments where the plane y = y0 cuts the mesh, as (x, z) pairs.
std::vector<std::array<Eigen::Vector2d, 2>> plane_cut(const mesh::Vertices& V,
                                                      const mesh::Faces& F,
                                                      double y0) {
    std::vector<std::array<Eigen::Vector2d, 2>> segs;
    for (Eigen::Index f = 0; f < F.rows(); ++f) {
        std::vector<Eigen::Vector2d> hits;
        for (int k = 0; k < 3; ++k) {
            const Eigen::Vector3d a = V.row(F(f, k));
            const Eigen::Vector3d b = V.row(F(f, (k + 1) % 3));
            const double da = a.y() - y0;
            const double db = b.y() - y0;
            if ((da < 0.0) == (db < 0.0)) continue;
            const double t = da / (da - db);
            hits.emplace_back(a.x() + t * (b.x() - a.x()), a.z() + t * (b.z() - a.z()));
        }
        if (hits.size() == 2) segs.push_back({hits[0], hits[1]});
    }
    return segs;
}

cv::Mat bscan_panel(const io::Scan& scan, const retina::OnhResult& r, int b) {
    const int W = scan.meta.size_x;
    const int H = scan.meta.size_z;
    const io::BScan& bs = scan.bscans[static_cast<std::size_t>(b)];
    cv::Mat grey(H, W, CV_8UC1, cv::Scalar(0));
    if (bs.pixels.size() == static_cast<std::size_t>(W) * static_cast<std::size_t>(H)) {
        for (int z = 0; z < H; ++z) {
            for (int x = 0; x < W; ++x) {
                const float v =
                    bs.pixels[static_cast<std::size_t>(z) * static_cast<std::size_t>(W) +
                              static_cast<std::size_t>(x)];
                const double d = (v >= io::kNoPixelData || !(v > 0.0F))
                                     ? 0.0
                                     : std::pow(static_cast<double>(v), 0.25);  // display
                grey.at<uchar>(z, x) =
                    static_cast<uchar>(std::lround(255 * std::clamp(d, 0.0, 1.0)));
            }
        }
    }
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
    for (const auto& s : plane_cut(r.ilm_V, r.ilm_F, b * g.dy_mm + 1e-7)) {
        cv::line(img, px(s[0].x(), s[0].y()), px(s[1].x(), s[1].y()), kUsedIlm, 1, cv::LINE_AA);
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
    outlined_text(img, "B-scan " + std::to_string(b), {6, 18}, 0.5, cv::Scalar(255, 255, 255));
    return img;
}

cv::Mat bscans_picture(const io::Scan& scan, const retina::OnhResult& r) {
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
    cv::Mat out(row.rows + 40, row.cols, CV_8UC3, cv::Scalar(30, 30, 30));
    row.copyTo(out(cv::Rect(0, 0, row.cols, row.rows)));
    outlined_text(out, "device ILM", {8, row.rows + 26}, 0.5, kDeviceIlm);
    outlined_text(out, "ILM used (" + r.ilm_source + ")", {110, row.rows + 26}, 0.5, kUsedIlm);
    outlined_text(out, "device BM", {290, row.rows + 26}, 0.5, kBm);
    outlined_text(out, "filled RPE", {390, row.rows + 26}, 0.5, kFilled);
    outlined_text(out, "BMO points", {490, row.rows + 26}, 0.5, kDisc);
    outlined_text(out, "MRW vectors", {600, row.rows + 26}, 0.5, kMrw);
    return out;
}

cv::Mat mrw_picture(const retina::OnhResult& r) {
    const int W = 900;
    const int H = 360;
    cv::Mat img(H, W, CV_8UC3, cv::Scalar(255, 255, 255));
    const cv::Rect plot(60, 30, W - 90, H - 80);
    cv::rectangle(img, plot, cv::Scalar(200, 200, 200), 1);
    double hi = 0.05;
    for (const double m : r.mrw_mm) hi = std::max(hi, m);
    hi *= 1.1;
    auto px = [&](double deg, double m) {
        return cv::Point(
            plot.x + static_cast<int>(std::lround(deg / 360.0 * plot.width)),
            plot.y + plot.height - static_cast<int>(std::lround(m / hi * plot.height)));
    };
    for (int k = 0; k < 12; ++k) {
        const double lo = std::max(0.0, 30.0 * k - 15.0);
        const double up = std::min(360.0, 30.0 * k + 15.0);
        const double m = r.mrw_sector_mm[static_cast<std::size_t>(k)];
        if (!std::isnan(m)) {
            cv::line(img, px(lo, m), px(up, m), cv::Scalar(40, 40, 200), 2);
            if (k == 0) cv::line(img, px(345.0, m), px(360.0, m), cv::Scalar(40, 40, 200), 2);
        }
        cv::putText(img, std::to_string(30 * k), px(30.0 * k, 0.0) + cv::Point(-10, 18),
                    cv::FONT_HERSHEY_SIMPLEX, 0.4, cv::Scalar(80, 80, 80), 1, cv::LINE_AA);
    }
    for (std::size_t i = 0; i < r.mrw_mm.size(); ++i) {
        cv::circle(img, px(r.bmo_anatomical_deg[i], r.mrw_mm[i]), 2, kMrw, -1);
    }
    cv::putText(img, printf_number("%.2f mm", hi), {4, plot.y + 10}, cv::FONT_HERSHEY_SIMPLEX, 0.4,
                cv::Scalar(80, 80, 80), 1, cv::LINE_AA);
    cv::putText(img,
                "MRW per BMO point (magenta), sector means (red) vs anatomical angle "
                "(0 nasal, 90 sup.); mean " +
                    printf_number("%.3f mm", r.mrw_mean_mm),
                {10, H - 14}, cv::FONT_HERSHEY_SIMPLEX, 0.42, cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
    return img;
}

}  // namespace

void write_onh_qc(const io::Scan& scan,
                  const retina::OnhResult& r,
                  const retina::OnhParams& p,
                  const std::string& dir,
                  const std::string& stem) {
    std::error_code ec;
    std::filesystem::create_directories(dir, ec);
    if (ec) throw OutputError(dir, "cannot create the QC directory: " + ec.message());
    const std::filesystem::path d(dir);
    save_png(enface_picture(r, p), (d / (stem + "_enface.png")).string());
    save_png(bscans_picture(scan, r), (d / (stem + "_bscans.png")).string());
    save_png(mrw_picture(r), (d / (stem + "_mrw.png")).string());
}

}  // namespace octshape::app
