#include "octshape/retina/bmo.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <numbers>
#include <opencv2/imgproc.hpp>
#include <sstream>
#include <utility>
#include <vector>

#include "octshape/error.h"

namespace octshape::retina {
namespace {

constexpr double kPi = std::numbers::pi;

std::string trim(const std::string& s) {
    const auto b = s.find_first_not_of(" \t\r\n");
    if (b == std::string::npos) return {};
    const auto e = s.find_last_not_of(" \t\r\n");
    return s.substr(b, e - b + 1);
}

std::vector<std::string> split(const std::string& s) {
    std::vector<std::string> out;
    std::stringstream ss(s);
    std::string item;
    while (std::getline(ss, item, ',')) out.push_back(trim(item));
    return out;
}

}  // namespace

void BmoDetectionParams::validate() const {
    if (!(min_gap_area_mm2 > 0.0) || !std::isfinite(min_gap_area_mm2)) {
        throw UsageError("min_gap_area_mm2 must be a positive number");
    }
}

BmoDetection detect_bmo_points(const GridSurface& bm, const BmoDetectionParams& params) {
    params.validate();
    const int nx = bm.cols;
    const int ny = bm.rows;
    const auto idx = [nx](int a, int b) {
        return static_cast<std::size_t>(b) * static_cast<std::size_t>(nx) +
               static_cast<std::size_t>(a);
    };
    const auto missing = [&](int a, int b) { return std::isnan(bm.z[idx(a, b)]); };
    // 4-connected components of missing nodes (iterative flood fill).
    std::vector<int> label(bm.z.size(), -1);
    std::vector<int> sizes;
    std::vector<std::pair<int, int>> stack;
    for (int b = 0; b < ny; ++b) {
        for (int a = 0; a < nx; ++a) {
            if (!missing(a, b) || label[idx(a, b)] >= 0) continue;
            const int id = static_cast<int>(sizes.size());
            int count = 0;
            stack.emplace_back(a, b);
            label[idx(a, b)] = id;
            while (!stack.empty()) {
                const auto [ca, cb] = stack.back();
                stack.pop_back();
                ++count;
                const std::array<std::pair<int, int>, 4> nb{
                    {{ca - 1, cb}, {ca + 1, cb}, {ca, cb - 1}, {ca, cb + 1}}};
                for (const auto& [na, nbb] : nb) {
                    if (na < 0 || nbb < 0 || na >= nx || nbb >= ny) continue;
                    if (!missing(na, nbb) || label[idx(na, nbb)] >= 0) continue;
                    label[idx(na, nbb)] = id;
                    stack.emplace_back(na, nbb);
                }
            }
            sizes.push_back(count);
        }
    }
    BmoDetection det;
    det.points_per_bscan.assign(static_cast<std::size_t>(ny), 0);
    if (sizes.empty()) {
        throw AnalysisError("no BMO: the BM segmentation has no gap (give the BMO with --bmo)");
    }
    const auto disc =
        static_cast<int>(std::max_element(sizes.begin(), sizes.end()) - sizes.begin());
    const double cell = bm.dx_mm * bm.dy_mm;
    det.gap_area_mm2 = sizes[static_cast<std::size_t>(disc)] * cell;
    det.other_gaps = static_cast<int>(sizes.size()) - 1;
    for (std::size_t i = 0; i < sizes.size(); ++i) {
        if (static_cast<int>(i) != disc) det.other_gap_nodes += sizes[i];
    }
    if (det.gap_area_mm2 < params.min_gap_area_mm2) {
        throw AnalysisError("no BMO: the largest gap of the BM segmentation covers only " +
                            std::to_string(det.gap_area_mm2) + " mm2 (< min_gap_area_mm2 " +
                            std::to_string(params.min_gap_area_mm2) + ")");
    }
    // Height of the end point: the present value next to the gap extrapolated by half an A-scan
    // (linear, from the two present values) so that z belongs to the point's x.
    // `step` points away from the gap: -1 at its start, +1 at its end.
    auto end_height = [&](int a_out, int step, int b) {
        const double z1 = bm.z[idx(a_out, b)];
        const int a2 = a_out + step;
        if (a2 >= 0 && a2 < nx && !missing(a2, b)) return z1 + 0.5 * (z1 - bm.z[idx(a2, b)]);
        return z1;
    };
    for (int b = 0; b < ny; ++b) {
        int a0 = -1;
        int a1 = -1;
        for (int a = 0; a < nx; ++a) {
            if (label[idx(a, b)] != disc) continue;
            if (a0 < 0) a0 = a;
            a1 = a;
        }
        if (a0 < 0) continue;
        const double y = b * bm.dy_mm;
        if (a0 - 1 >= 0 && !missing(a0 - 1, b)) {
            BmoPoint p;
            p.mm = Eigen::Vector3d((a0 - 0.5) * bm.dx_mm, y, end_height(a0 - 1, -1, b));
            p.bscan = b;
            p.side = -1;
            det.points.push_back(p);
            ++det.points_per_bscan[static_cast<std::size_t>(b)];
        }
        if (a1 + 1 < nx && !missing(a1 + 1, b)) {
            BmoPoint p;
            p.mm = Eigen::Vector3d((a1 + 0.5) * bm.dx_mm, y, end_height(a1 + 1, +1, b));
            p.bscan = b;
            p.side = +1;
            det.points.push_back(p);
            ++det.points_per_bscan[static_cast<std::size_t>(b)];
        }
    }
    if (det.points.size() < 6) {
        throw AnalysisError("no BMO: only " + std::to_string(det.points.size()) +
                            " BMO end points found (an ellipse needs at least 6)");
    }
    return det;
}

std::vector<BmoPoint> read_bmo_csv(const std::string& path,
                                   const io::ScanMeta& meta,
                                   int num_bscans,
                                   bool* pixel_header) {
    std::ifstream in(path);
    if (!in) throw InputError::missing(path);
    std::string line;
    int line_no = 0;
    bool pixels = false;
    bool header = false;
    std::vector<BmoPoint> pts;
    const double width = (meta.size_x - 1) * meta.scale_x_mm;
    const double height = (num_bscans - 1) * meta.distance_mm;
    while (std::getline(in, line)) {
        ++line_no;
        const std::string t = trim(line);
        if (t.empty() || t.front() == '#') continue;
        const auto f = split(t);
        const std::string where = "line " + std::to_string(line_no);
        if (!header) {
            if (f == std::vector<std::string>{"x_mm", "y_mm", "z_mm"}) {
                pixels = false;
            } else if (f == std::vector<std::string>{"ascan", "bscan", "depth_px"}) {
                pixels = true;
            } else {
                throw InputError::corrupt(path, where +
                                                    ": the header must be 'x_mm,y_mm,z_mm' or "
                                                    "'ascan,bscan,depth_px'");
            }
            header = true;
            continue;
        }
        if (f.size() != 3) {
            throw InputError::corrupt(path, where + ": expected 3 comma-separated numbers");
        }
        std::array<double, 3> v{};
        for (std::size_t k = 0; k < 3; ++k) {
            std::size_t used = 0;
            try {
                v[k] = std::stod(f[k], &used);
            } catch (const std::exception&) {
                used = 0;
            }
            if (used != f[k].size() || f[k].empty() || !std::isfinite(v[k])) {
                throw InputError::corrupt(path, where + ": '" + f[k] + "' is not a number");
            }
        }
        BmoPoint p;
        p.mm = pixels ? Eigen::Vector3d(v[0] * meta.scale_x_mm, v[1] * meta.distance_mm,
                                        -v[2] * meta.scale_z_mm)
                      : Eigen::Vector3d(v[0], v[1], v[2]);
        const double tol = 1e-9;
        if (p.mm.x() < -tol || p.mm.x() > width + tol || p.mm.y() < -tol ||
            p.mm.y() > height + tol) {
            throw InputError::corrupt(path, where + ": the point lies outside the scan grid");
        }
        pts.push_back(p);
    }
    if (!header) throw InputError::corrupt(path, "no header line");
    if (pixel_header != nullptr) *pixel_header = pixels;
    if (pts.size() < 6) {
        throw InputError::corrupt(path, "only " + std::to_string(pts.size()) +
                                            " BMO points (an ellipse needs at least 6)");
    }
    return pts;
}

double BmoEllipse::normalised_radius(double x, double y) const {
    const double th = orientation_deg * kPi / 180.0;
    const double dx = x - centre_mm.x();
    const double dy = y - centre_mm.y();
    const double u = (std::cos(th) * dx + std::sin(th) * dy) / semi_major_mm;
    const double v = (-std::sin(th) * dx + std::cos(th) * dy) / semi_minor_mm;
    return std::hypot(u, v);
}

bool BmoEllipse::inside(double x, double y) const { return normalised_radius(x, y) < 1.0; }

namespace {

// The BMO height at polar angle `ang` about the ellipse centre: linear in angle between the
// two measured points that bracket it (periodic; `polar_z` sorted by angle). It was the
// nearest point's height, a step function: on a tilted BMO or with the B-scans' residual
// axial offsets it jumped at every switch (5-40 um between neighbouring 1 deg points), and the
// 3-D MRW with it (docs/algorithms/onh.md "3-D MRW per point").
double bmo_height_at_angle(const std::vector<std::pair<double, double>>& polar_z, double ang) {
    const std::size_t n = polar_z.size();
    auto upper = std::upper_bound(polar_z.begin(), polar_z.end(), ang,
                                  [](double v, const std::pair<double, double>& p) {
                                      return v < p.first;
                                  });
    const std::size_t j = static_cast<std::size_t>(upper - polar_z.begin()) % n;  // after
    const std::size_t i = (j + n - 1) % n;                                         // before
    double span = polar_z[j].first - polar_z[i].first;
    double from_i = ang - polar_z[i].first;
    if (span <= 0.0) span += 2.0 * kPi;  // the pair straddles +-pi (or n == 1)
    if (from_i < 0.0) from_i += 2.0 * kPi;
    if (!(span > 1e-12)) return 0.5 * (polar_z[i].second + polar_z[j].second);
    const double w = std::clamp(from_i / span, 0.0, 1.0);
    return (1.0 - w) * polar_z[i].second + w * polar_z[j].second;
}

}  // namespace

BmoEllipse fit_bmo_ellipse(const std::vector<BmoPoint>& points, int num_points) {
    if (points.size() < 6) {
        throw AnalysisError("BMO ellipse: " + std::to_string(points.size()) +
                            " points (at least 6 needed)");
    }
    if (num_points < 8) throw UsageError("the number of resampled BMO points must be >= 8");
    // Centre the points first: cv::fitEllipseDirect takes floats.
    Eigen::Vector2d mean = Eigen::Vector2d::Zero();
    for (const auto& p : points) mean += p.mm.head<2>();
    mean /= static_cast<double>(points.size());
    std::vector<cv::Point2f> pts;
    pts.reserve(points.size());
    for (const auto& p : points) {
        pts.emplace_back(static_cast<float>(p.mm.x() - mean.x()),
                         static_cast<float>(p.mm.y() - mean.y()));
    }
    const cv::RotatedRect r = cv::fitEllipseDirect(pts);
    // RotatedRect: `width` is the full axis along (cos angle, sin angle) in the points' own
    // (x, y) frame (checked by BmoEllipse.RecoversAKnownEllipse).
    double a = 0.5 * r.size.width;
    double b = 0.5 * r.size.height;
    double th = r.angle;
    if (b > a) {
        std::swap(a, b);
        th += 90.0;
    }
    if (!(b > 0.0) || !std::isfinite(a) || !std::isfinite(th)) {
        throw AnalysisError("BMO ellipse: the fit is degenerate (points collinear?)");
    }
    th = std::fmod(std::fmod(th, 180.0) + 180.0, 180.0);
    BmoEllipse e;
    e.centre_mm = mean + Eigen::Vector2d(r.center.x, r.center.y);
    e.semi_major_mm = a;
    e.semi_minor_mm = b;
    e.orientation_deg = th;
    e.area_mm2 = kPi * a * b;  // Eq. 8.24
    double ss = 0.0;
    std::vector<std::pair<double, double>> polar_z;  // (polar angle about the centre, z)
    polar_z.reserve(points.size());
    for (const auto& p : points) {
        const double rho = e.normalised_radius(p.mm.x(), p.mm.y());
        const double dist = (p.mm.head<2>() - e.centre_mm).norm();
        const double radial = rho > 0.0 ? dist * (1.0 - 1.0 / rho) : 0.0;
        ss += radial * radial;
        polar_z.emplace_back(std::atan2(p.mm.y() - e.centre_mm.y(), p.mm.x() - e.centre_mm.x()),
                             p.mm.z());
    }
    e.rms_residual_mm = std::sqrt(ss / static_cast<double>(points.size()));
    std::sort(polar_z.begin(), polar_z.end());
    const double ct = std::cos(th * kPi / 180.0);
    const double st = std::sin(th * kPi / 180.0);
    for (int i = 0; i < num_points; ++i) {
        const double t = 2.0 * kPi * i / num_points;
        const double u = a * std::cos(t);
        const double v = b * std::sin(t);
        const Eigen::Vector2d xy = e.centre_mm + Eigen::Vector2d(ct * u - st * v, st * u + ct * v);
        const double ang = std::atan2(xy.y() - e.centre_mm.y(), xy.x() - e.centre_mm.x());
        e.points_mm.emplace_back(xy.x(), xy.y(), bmo_height_at_angle(polar_z, ang));
        e.parameter_rad.push_back(t);
    }
    return e;
}

}  // namespace octshape::retina
