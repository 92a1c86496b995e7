#include "octshape/retina/phantom_onh.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <functional>
#include <limits>
#include <numbers>
#include <span>
#include <string>
#include <utility>

#include <Eigen/Eigenvalues>
#include <Eigen/LU>

#include "octshape/error.h"
#include "octshape/retina/phantom_common.h"
#include "octshape/version.h"

namespace octshape::retina {
namespace {

constexpr double kPi = std::numbers::pi;
constexpr double kDiscRadiusMm = 1.5;  // total / annular volume disc (docs/algorithms/onh.md)
// Outside the BMO the ILM must stay this far above the BM (the cavity of an overhang may not
// pass under Bruch's membrane, and every column needs some retina to draw).
constexpr double kMinClearanceMm = 0.01;

void require(bool ok, const std::string& field, const std::string& why) {
    if (!ok) throw UsageError("phantom onh: " + field + " " + why);
}

bool finite_positive(double v) { return std::isfinite(v) && v > 0.0; }

// 8-point Gauss-Legendre rule on [-1, 1].
constexpr std::array<double, 8> kGlNodes = {
    -0.9602898564975363, -0.7966664774136267, -0.5255324099163290, -0.1834346424956498,
    0.1834346424956498,  0.5255324099163290,  0.7966664774136267,  0.9602898564975363};
constexpr std::array<double, 8> kGlWeights = {
    0.1012285362903763, 0.2223810344533745, 0.3137066458778873, 0.3626837833783620,
    0.3626837833783620, 0.3137066458778873, 0.2223810344533745, 0.1012285362903763};

// Composite 8-point Gauss-Legendre over [lo, hi] with sub-intervals no longer than `step`.
template <typename F>
void gauss_legendre(double lo, double hi, double step, F&& node) {
    if (!(hi > lo)) return;
    const int n = std::max(1, static_cast<int>(std::ceil((hi - lo) / step - 1e-9)));
    const double h = (hi - lo) / n;
    for (int i = 0; i < n; ++i) {
        const double mid = lo + (i + 0.5) * h;
        for (std::size_t k = 0; k < kGlNodes.size(); ++k) {
            node(mid + 0.5 * h * kGlNodes[k], 0.5 * h * kGlWeights[k]);
        }
    }
}

// Every root of fn on [lo, hi], found by sampling `samples` intervals for sign changes and
// bisecting each to machine precision. A root where fn only touches zero is not found; the
// callers' functions cross their levels.
std::vector<double> find_roots(const std::function<double(double)>& fn,
                               double lo,
                               double hi,
                               int samples) {
    std::vector<double> roots;
    double a = lo;
    double fa = fn(a);
    if (fa == 0.0) roots.push_back(a);
    for (int i = 1; i <= samples; ++i) {
        const double b = lo + (hi - lo) * i / samples;
        const double fb = fn(b);
        if (fb == 0.0) {
            roots.push_back(b);
        } else if (fa != 0.0 && (fa < 0.0) != (fb < 0.0)) {
            double l = a;
            double r = b;
            double fl = fa;
            for (int it = 0; it < 200; ++it) {
                const double m = 0.5 * (l + r);
                if (m <= l || m >= r) break;
                const double fm = fn(m);
                if (fm == 0.0) {
                    l = r = m;
                    break;
                }
                if ((fm < 0.0) == (fl < 0.0)) {
                    l = m;
                    fl = fm;
                } else {
                    r = m;
                }
            }
            roots.push_back(0.5 * (l + r));
        }
        a = b;
        fa = fb;
    }
    return roots;
}

// Sorted, de-duplicated break points clipped to [lo, hi], with lo and hi included.
std::vector<double> breaks_in(std::vector<double> pts, double lo, double hi) {
    pts.push_back(lo);
    pts.push_back(hi);
    std::vector<double> out;
    std::sort(pts.begin(), pts.end());
    for (double p : pts) {
        if (p < lo || p > hi) continue;
        if (out.empty() || p - out.back() > 1e-13) out.push_back(p);
    }
    return out;
}

// True when two segments properly intersect (shared end points of neighbours excluded by the
// caller).
bool segments_cross(const Eigen::Vector2d& p1,
                    const Eigen::Vector2d& p2,
                    const Eigen::Vector2d& q1,
                    const Eigen::Vector2d& q2) {
    auto cross = [](const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
        return a.x() * b.y() - a.y() * b.x();
    };
    const double d1 = cross(p2 - p1, q1 - p1);
    const double d2 = cross(p2 - p1, q2 - p1);
    const double d3 = cross(q2 - q1, p1 - q1);
    const double d4 = cross(q2 - q1, p2 - q1);
    return ((d1 > 0) != (d2 > 0)) && ((d3 > 0) != (d4 > 0)) && d1 != 0 && d2 != 0 && d3 != 0 &&
           d4 != 0;
}

phantom::VolumeLayout layout_of(const OnhPhantomParams& p) {
    phantom::VolumeLayout l;
    l.pattern = io::ScanPattern::kVolume;
    l.laterality = p.eye;
    l.size_x = p.num_ascans;
    l.size_z = p.depth_px;
    l.num_bscans = p.num_bscans;
    l.scale_x_mm = p.field_mm / p.num_ascans;
    l.scale_z_mm = p.scale_z_mm;
    l.distance_mm = p.field_mm / (p.num_bscans - 1);
    l.num_seg = 2;  // ILM and BM, as in many Spectralis ONH exports
    l.slo_size_px = 256;
    l.slo_margin = 2.0;  // a 30 deg SLO around the 15 deg volume
    l.slo_field_deg = 30;
    return l;
}

}  // namespace

std::string to_string(OnhShape shape) {
    switch (shape) {
        case OnhShape::kCupped:
            return "cupped";
        case OnhShape::kSwollen:
            return "swollen";
        case OnhShape::kOverhang:
            return "overhang";
    }
    return "unknown";
}

std::string to_string(CupProfile profile) {
    return profile == CupProfile::kSpherical ? "spherical" : "bowl";
}

void OnhProfileParams::validate() const {
    require(std::isfinite(retina_thickness_mm) && retina_thickness_mm >= kMinClearanceMm,
            "retina_thickness_mm", "must be >= 0.01");
    require(std::isfinite(rim_height_mm) && rim_height_mm >= 0.0, "rim_height_mm", "must be >= 0");
    require(finite_positive(rim_radius), "rim_radius", "must be > 0");
    require(std::isfinite(swelling_mm) && swelling_mm >= 0.0, "swelling_mm", "must be >= 0");
    require(finite_positive(swelling_width), "swelling_width", "must be > 0");
    require(std::isfinite(cup_depth_mm) && cup_depth_mm >= 0.0, "cup_depth_mm", "must be >= 0");
    require(finite_positive(cup_radius), "cup_radius", "must be > 0");
    require(cup_exponent >= 2 && cup_exponent <= 32 && cup_exponent % 2 == 0, "cup_exponent",
            "must be even, in 2..32");
    require(std::isfinite(undercut) && undercut >= 0.0 && undercut < 1.0, "undercut",
            "must be in [0, 1)");
    require(std::isfinite(undercut_height_mm), "undercut_height_mm", "must be finite");
    require(finite_positive(undercut_halfwidth_mm), "undercut_halfwidth_mm", "must be > 0");
    if (undercut > 0.0) {
        // The push must vanish far from the disc, where the ILM is at least T above the BM.
        require(undercut_height_mm + undercut_halfwidth_mm <= retina_thickness_mm,
                "undercut_height_mm", "+ undercut_halfwidth_mm must be <= retina_thickness_mm");
    }
}

void OnhPhantomParams::validate() const {
    require(
        shape == OnhShape::kCupped || shape == OnhShape::kSwollen || shape == OnhShape::kOverhang,
        "shape", "is unknown");
    require(eye == io::Laterality::kOD || eye == io::Laterality::kOS, "eye", "must be OD or OS");
    artefacts.validate();
    require(num_bscans >= 5 && num_bscans <= 1024, "bscans", "must be in 5..1024");
    require(num_ascans >= 16 && num_ascans <= 4096, "ascans", "must be in 16..4096");
    require(depth_px >= 64 && depth_px <= 4096, "depth", "must be in 64..4096");
    require(finite_positive(field_mm) && field_mm <= 12.0, "field_mm", "must be in (0, 12]");
    require(finite_positive(scale_z_mm) && scale_z_mm < 0.1, "scale_z_mm", "must be in (0, 0.1)");
    require(std::isfinite(bm_centre_depth_fraction) && bm_centre_depth_fraction > 0.0 &&
                bm_centre_depth_fraction < 1.0,
            "bm_centre_depth_fraction", "must be in (0, 1)");
    require(std::isfinite(bmo_offset_x_mm) && std::isfinite(bmo_offset_y_mm), "bmo_offset_mm",
            "must be finite");
    require(finite_positive(bmo_semi_minor_mm), "bmo_semi_minor_mm", "must be > 0");
    require(std::isfinite(bmo_semi_major_mm) && bmo_semi_major_mm >= bmo_semi_minor_mm,
            "bmo_semi_major_mm", "must be >= bmo_semi_minor_mm");
    require(bmo_semi_major_mm < kDiscRadiusMm, "bmo_semi_major_mm",
            "must be < 1.5 (the BMO must lie inside the 1.5 mm disc)");
    require(std::isfinite(bmo_rotation_deg), "bmo_rotation_deg", "must be finite");
    require(std::isfinite(eye_radius_mm) && (eye_radius_mm == 0.0 || eye_radius_mm >= 3.0),
            "eye_radius_mm", "must be 0 (flat) or >= 3");
    require(std::isfinite(tilt_x) && std::fabs(tilt_x) <= 0.5, "tilt_x", "must be in [-0.5, 0.5]");
    require(std::isfinite(tilt_y) && std::fabs(tilt_y) <= 0.5, "tilt_y", "must be in [-0.5, 0.5]");
    require(speckle_looks >= 1 && speckle_looks <= 64, "speckle_looks", "must be in 1..64");
    for (const double w : {speckle_axial_half_width_px, speckle_lateral_half_width_px}) {
        require(w >= 0.0 && w <= 20.0, "speckle grain", "half-widths must be in 0..20 px");
    }
    profile.validate();
    if (radial) {
        // At least 3 lines (6 BMO points) for the ellipse; the 1.5 mm disc around the BMO centre
        // must lie inside the scanned circle (radius half a line about the crossing).
        require(radial_lines >= 3 && radial_lines <= 360, "radial_lines", "must be in 3..360");
        require(std::isfinite(line_length_mm) && line_length_mm >= 2.0 && line_length_mm <= 12.0,
                "line_length_mm", "must be in [2, 12] mm");
        require(std::isfinite(crossing_offset_um) && std::fabs(crossing_offset_um) <= 500.0,
                "crossing_offset_um", "must be within +-500 um");
        require(std::isfinite(crossing_offset_y_um) &&
                    std::hypot(crossing_offset_um, crossing_offset_y_um) <= 500.0,
                "crossing_offset_y_um", "must keep the crossing within 500 um of the BMO centre");
        require(0.5 * line_length_mm >=
                    kDiscRadiusMm + 1e-3 * std::hypot(crossing_offset_um, crossing_offset_y_um),
                "line_length_mm",
                "puts the 1.5 mm disc around the BMO centre outside the scanned circle (half "
                "the line length must be >= 1.5 mm + the crossing offset)");
    }
    // The 1.5 mm disc around the BMO centre must lie inside the scanned area, so that the total
    // and annular volumes refer to tissue the scan holds.
    const double width = (num_ascans - 1) * field_mm / num_ascans;
    const double height = field_mm;
    const double cx = width / 2 + bmo_offset_x_mm;
    const double cy = height / 2 + bmo_offset_y_mm;
    require(cx - kDiscRadiusMm >= 0.0 && cx + kDiscRadiusMm <= width && cy - kDiscRadiusMm >= 0.0 &&
                cy + kDiscRadiusMm <= height,
            "bmo_offset_mm", "puts the 1.5 mm disc around the BMO centre outside the scan");
}

OnhProfileParams onh_profile_preset(OnhShape shape) {
    OnhProfileParams p;
    switch (shape) {
        case OnhShape::kCupped:
            break;  // the struct defaults
        case OnhShape::kSwollen:
            p.rim_height_mm = 0.10;
            p.swelling_mm = 0.55;
            p.swelling_width = 0.9;
            p.cup_depth_mm = 0.12;  // a shallow central dip that stays above the RPE
            p.cup_radius = 0.35;
            p.cup_exponent = 2;
            break;
        case OnhShape::kOverhang:
            p.rim_height_mm = 0.20;
            p.rim_radius = 1.1;
            p.cup_depth_mm = 0.75;
            p.cup_radius = 0.75;
            p.cup_exponent = 8;
            p.undercut = 0.20;
            p.undercut_height_mm = 0.05;
            p.undercut_halfwidth_mm = 0.20;
            break;
    }
    return p;
}

OnhPhantomParams onh_phantom_preset(OnhShape shape) {
    OnhPhantomParams p;
    p.shape = shape;
    p.profile = onh_profile_preset(shape);
    return p;
}

Eigen::Vector2d onh_radial_crossing(const OnhPhantomParams& p) {
    const phantom::GridFrame f = phantom::grid_frame(layout_of(p));
    return f.centre_mm() + Eigen::Vector2d(p.bmo_offset_x_mm + 1e-3 * p.crossing_offset_um,
                                           p.bmo_offset_y_mm + 1e-3 * p.crossing_offset_y_um);
}

Eigen::Vector2d onh_radial_direction(const OnhPhantomParams& p, int k) {
    const double a = kPi * k / p.radial_lines;
    return {std::cos(a), std::sin(a)};
}

std::vector<Eigen::Vector2d> onh_sample_points(const OnhPhantomParams& p) {
    p.validate();
    std::vector<Eigen::Vector2d> pts;
    if (p.radial) {
        const Eigen::Vector2d c = onh_radial_crossing(p);
        const double step = p.line_length_mm / (p.num_ascans - 1);
        pts.reserve(static_cast<std::size_t>(p.radial_lines) *
                    static_cast<std::size_t>(p.num_ascans));
        for (int k = 0; k < p.radial_lines; ++k) {
            const Eigen::Vector2d u = onh_radial_direction(p, k);
            for (int a = 0; a < p.num_ascans; ++a) {
                pts.push_back(c + (a * step - 0.5 * p.line_length_mm) * u);
            }
        }
        return pts;
    }
    const phantom::VolumeLayout l = layout_of(p);
    pts.reserve(static_cast<std::size_t>(l.num_bscans) * static_cast<std::size_t>(l.size_x));
    for (int b = 0; b < l.num_bscans; ++b) {
        for (int a = 0; a < l.size_x; ++a) pts.emplace_back(a * l.scale_x_mm, b * l.distance_mm);
    }
    return pts;
}

// ---------------------------------------------------------------------------------------------
// Geometry

OnhPhantomGeometry::OnhPhantomGeometry(const OnhPhantomParams& params)
    : profile_(params.profile),
      scale_x_mm_(params.field_mm / params.num_ascans),
      distance_mm_(params.field_mm / (params.num_bscans - 1)),
      scale_z_mm_(params.scale_z_mm),
      semi_major_mm_(params.bmo_semi_major_mm) {
    params.validate();
    const double width = (params.num_ascans - 1) * scale_x_mm_;
    const double height = (params.num_bscans - 1) * distance_mm_;
    centre_ = {width / 2 + params.bmo_offset_x_mm, height / 2 + params.bmo_offset_y_mm};
    const double t = params.bmo_rotation_deg * kPi / 180.0;
    Eigen::Matrix2d rot;
    rot << std::cos(t), -std::sin(t), std::sin(t), std::cos(t);
    frame_ = rot * Eigen::Vector2d(params.bmo_semi_major_mm, params.bmo_semi_minor_mm).asDiagonal();
    frame_inv_ = frame_.inverse();
    curvature_ = params.eye_radius_mm > 0.0 ? 1.0 / params.eye_radius_mm : 0.0;
    tilt_ = {params.tilt_x, params.tilt_y};
    z_centre_ = -params.bm_centre_depth_fraction * params.depth_px * scale_z_mm_;
    const double d = profile_.cup_depth_mm;
    if (profile_.cup_profile == CupProfile::kSpherical && d > 0.0) {
        const double r = profile_.cup_radius * semi_major_mm_;
        sphere_radius_mm_ = (r * r + d * d) / (2.0 * d);
        require(r <= sphere_radius_mm_, "cup_depth_mm",
                "must be <= the cup radius for a spherical cup");
    }
    // Every column of the grid lies within s_max (rho(s) >= s, so roots have s <= rho).
    for (double x : {0.0, width}) {
        for (double y : {0.0, height}) s_max_ = std::max(s_max_, normalised(x, y).norm());
    }
    if (params.radial) {  // the radial lines' ends (the farthest A-scans of each line)
        const Eigen::Vector2d cross =
            centre_ + 1e-3 * Eigen::Vector2d(params.crossing_offset_um, params.crossing_offset_y_um);
        for (int k = 0; k < params.radial_lines; ++k) {
            const double a = kPi * k / params.radial_lines;
            const Eigen::Vector2d u(std::cos(a), std::sin(a));
            for (double sgn : {-1.0, 1.0}) {
                const Eigen::Vector2d e = cross + sgn * 0.5 * params.line_length_mm * u;
                s_max_ = std::max(s_max_, normalised(e.x(), e.y()).norm());
            }
        }
    }
    s_max_ = std::max(s_max_ + 0.05, profile_.cup_radius + 0.05);
    // Lateral jitter moves a volume's A-scans off the grid by up to its largest shift
    // (phantom::acquired_points): the columns the pixels sample reach that far. s_max, and so
    // every truth value, stays the still grid's.
    reach_ = s_max_;
    if (!params.radial && params.artefacts.lateral_jitter_um > 0.0) {
        const phantom::AcquisitionShifts sh =
            phantom::acquisition_shifts(params.artefacts, params.num_bscans, scale_z_mm_,
                                        scale_x_mm_, false, params.seed);
        double out = 0.0;
        for (double px : sh.lateral_px) out = std::max(out, std::fabs(px) * scale_x_mm_);
        for (double x : {-out, width + out}) {
            for (double y : {0.0, height}) {
                reach_ = std::max(reach_, normalised(x, y).norm() + 0.05);
            }
        }
    }

    // Monotone pieces of rho(s): split at the roots of rho'(s).
    pieces_ = {0.0};
    if (profile_.undercut > 0.0) {
        const auto turns = find_roots([this](double s) { return drho(s); }, 0.0, s_max_, 40000);
        for (double s : turns) {
            if (s > pieces_.back() + 1e-12) pieces_.push_back(s);
        }
    }
    pieces_.push_back(s_max_);

    // Shape checks on the generating curve.
    require(std::fabs(rho(0.0)) < 1e-15, "undercut_height_mm",
            "- undercut_halfwidth_mm must lie above the cup floor (the curve must start on the "
            "axis)");
    const int n = 3000;
    const double s_check = std::min(s_max_, profile_.cup_radius + 2.5);
    std::vector<Eigen::Vector2d> poly;
    poly.reserve(n + 1);
    for (int i = 0; i <= n; ++i) {
        const double s = s_check * i / n;
        const double r = rho(s);
        poly.emplace_back(r, w(s));
        require(r < 1.0 || w(s) >= kMinClearanceMm, "profile",
                "puts the ILM below the BM outside the BMO (at normalised radius " +
                    std::to_string(r) + ")");
    }
    if (profile_.undercut > 0.0) {
        for (int i = 0; i + 1 < n; ++i) {
            for (int j = i + 2; j + 1 <= n; ++j) {
                require(!segments_cross(poly[static_cast<std::size_t>(i)],
                                        poly[static_cast<std::size_t>(i + 1)],
                                        poly[static_cast<std::size_t>(j)],
                                        poly[static_cast<std::size_t>(j + 1)]),
                        "undercut", "makes the ILM intersect itself");
            }
        }
    }
}

double OnhPhantomGeometry::bm_height(double x, double y) const {
    const Eigen::Vector2d d(x - centre_.x(), y - centre_.y());
    return z_centre_ + 0.5 * curvature_ * d.squaredNorm() + tilt_.dot(d);
}

Eigen::Vector2d OnhPhantomGeometry::bm_gradient(double x, double y) const {
    const Eigen::Vector2d d(x - centre_.x(), y - centre_.y());
    return curvature_ * d + tilt_;
}

Eigen::Vector2d OnhPhantomGeometry::normalised(double x, double y) const {
    return frame_inv_ * Eigen::Vector2d(x - centre_.x(), y - centre_.y());
}

namespace {

// Smooth (C2) compactly supported bump (1 - x^2)^3 and its derivative in x.
double bump(double x) {
    if (std::fabs(x) >= 1.0) return 0.0;
    const double q = 1.0 - x * x;
    return q * q * q;
}
double dbump(double x) {
    if (std::fabs(x) >= 1.0) return 0.0;
    const double q = 1.0 - x * x;
    return -6.0 * x * q * q;
}

}  // namespace

double OnhPhantomGeometry::w(double s) const {
    const auto& p = profile_;
    double v = p.retina_thickness_mm;
    if (p.rim_height_mm != 0.0) {
        const double u = s * s / (p.rim_radius * p.rim_radius);
        v += p.rim_height_mm * u * std::exp(1.0 - u);
    }
    if (p.swelling_mm != 0.0) {
        v += p.swelling_mm * std::exp(-s * s / (2.0 * p.swelling_width * p.swelling_width));
    }
    if (p.cup_depth_mm > 0.0 && s < p.cup_radius) {
        if (p.cup_profile == CupProfile::kSpherical) {
            const double r = s * semi_major_mm_;
            const double rs = sphere_radius_mm_;
            v += -p.cup_depth_mm + (rs - std::sqrt(rs * rs - r * r));
        } else {
            const double q = 1.0 - std::pow(s / p.cup_radius, p.cup_exponent);
            v -= p.cup_depth_mm * q * q * q;
        }
    }
    return v;
}

double OnhPhantomGeometry::dw(double s) const {
    const auto& p = profile_;
    double v = 0.0;
    if (p.rim_height_mm != 0.0) {
        const double rr = p.rim_radius * p.rim_radius;
        const double u = s * s / rr;
        v += p.rim_height_mm * std::exp(1.0 - u) * (1.0 - u) * 2.0 * s / rr;
    }
    if (p.swelling_mm != 0.0) {
        const double ss = p.swelling_width * p.swelling_width;
        v -= p.swelling_mm * std::exp(-s * s / (2.0 * ss)) * s / ss;
    }
    if (p.cup_depth_mm > 0.0 && s < p.cup_radius) {
        if (p.cup_profile == CupProfile::kSpherical) {
            const double r = s * semi_major_mm_;
            const double rs = sphere_radius_mm_;
            v += semi_major_mm_ * r / std::sqrt(rs * rs - r * r);
        } else {
            const int k = p.cup_exponent;
            const double t = s / p.cup_radius;
            const double tk1 = std::pow(t, k - 1);
            const double q = 1.0 - tk1 * t;
            v += p.cup_depth_mm * 3.0 * q * q * k * tk1 / p.cup_radius;
        }
    }
    return v;
}

double OnhPhantomGeometry::rho(double s) const {
    const auto& p = profile_;
    if (p.undercut == 0.0) return s;
    return s + p.undercut * bump((w(s) - p.undercut_height_mm) / p.undercut_halfwidth_mm);
}

double OnhPhantomGeometry::drho(double s) const {
    const auto& p = profile_;
    if (p.undercut == 0.0) return 1.0;
    const double x = (w(s) - p.undercut_height_mm) / p.undercut_halfwidth_mm;
    return 1.0 + p.undercut * dbump(x) * dw(s) / p.undercut_halfwidth_mm;
}

std::vector<double> OnhPhantomGeometry::rho_roots(double target) const {
    std::vector<double> roots;
    if (profile_.undercut == 0.0) {
        if (target >= 0.0 && target <= reach_) roots.push_back(target);
        return roots;
    }
    // The root in [lo, hi] of a monotone piece whose ends bracket it (flo = rho(lo) - target).
    const auto bisect = [&](double lo, double hi, double flo) {
        for (int it = 0; it < 200; ++it) {
            const double m = 0.5 * (lo + hi);
            if (m <= lo || m >= hi) break;
            if (((rho(m) - target) < 0.0) == (flo < 0.0)) {
                lo = m;
            } else {
                hi = m;
            }
        }
        return 0.5 * (lo + hi);
    };
    for (std::size_t i = 0; i + 1 < pieces_.size(); ++i) {
        const double lo = pieces_[i];
        const double hi = pieces_[i + 1];
        const double flo = rho(lo) - target;
        const double fhi = rho(hi) - target;
        if (flo == 0.0) {
            roots.push_back(lo);
            continue;
        }
        if ((flo < 0.0) == (fhi < 0.0)) continue;  // fhi == 0 is the next piece's lo
        roots.push_back(bisect(lo, hi, flo));
    }
    if (std::fabs(rho(pieces_.back()) - target) == 0.0) roots.push_back(pieces_.back());
    // Beyond s_max (jittered columns only): rho(s) = s there (no undercut so far out).
    if (reach_ > s_max_ && target > rho(s_max_) && target <= rho(reach_)) {
        roots.push_back(bisect(s_max_, reach_, rho(s_max_) - target));
    }
    std::vector<double> out;
    for (double r : roots) {
        if (out.empty() || r - out.back() > 1e-12) out.push_back(r);
    }
    return out;
}

std::vector<double> OnhPhantomGeometry::crossings(double r) const {
    std::vector<double> out;
    for (double s : rho_roots(r)) out.push_back(w(s));
    std::sort(out.begin(), out.end(), std::greater<>());
    return out;
}

std::vector<double> OnhPhantomGeometry::kinks() const {
    std::vector<double> k;
    if (profile_.cup_depth_mm > 0.0) k.push_back(profile_.cup_radius);
    if (profile_.undercut > 0.0) {
        for (double level : {profile_.undercut_height_mm - profile_.undercut_halfwidth_mm,
                             profile_.undercut_height_mm + profile_.undercut_halfwidth_mm}) {
            const auto r = find_roots([&](double s) { return w(s) - level; }, 0.0, s_max_, 20000);
            k.insert(k.end(), r.begin(), r.end());
        }
    }
    std::sort(k.begin(), k.end());
    return k;
}

Eigen::Vector3d OnhPhantomGeometry::surface(double s, double phi) const {
    const double r = rho(s);
    const Eigen::Vector2d xy =
        centre_ + frame_ * Eigen::Vector2d(r * std::cos(phi), r * std::sin(phi));
    return {xy.x(), xy.y(), bm_height(xy.x(), xy.y()) + w(s)};
}

Eigen::Vector3d OnhPhantomGeometry::surface_ds(double s, double phi) const {
    const double r = rho(s);
    const double dr = drho(s);
    const Eigen::Vector2d xy =
        centre_ + frame_ * Eigen::Vector2d(r * std::cos(phi), r * std::sin(phi));
    const Eigen::Vector2d d = frame_ * Eigen::Vector2d(dr * std::cos(phi), dr * std::sin(phi));
    return {d.x(), d.y(), bm_gradient(xy.x(), xy.y()).dot(d) + dw(s)};
}

Eigen::Vector3d OnhPhantomGeometry::surface_dphi(double s, double phi) const {
    const double r = rho(s);
    const Eigen::Vector2d xy =
        centre_ + frame_ * Eigen::Vector2d(r * std::cos(phi), r * std::sin(phi));
    const Eigen::Vector2d d = frame_ * Eigen::Vector2d(-r * std::sin(phi), r * std::cos(phi));
    return {d.x(), d.y(), bm_gradient(xy.x(), xy.y()).dot(d)};
}

std::vector<double> OnhPhantomGeometry::ilm_heights(double x, double y) const {
    std::vector<double> h = crossings(normalised(x, y).norm());
    const double zb = bm_height(x, y);
    for (double& v : h) v += zb;
    return h;
}

bool OnhPhantomGeometry::in_tissue(double x, double y, double z) const {
    // Point-in-region test in the meridian half-plane: count the ILM crossings above z; the
    // vitreous is above every crossing, so an odd count means tissue.
    int above = 0;
    for (double h : ilm_heights(x, y)) above += h > z ? 1 : 0;
    return above % 2 == 1;
}

}  // namespace octshape::retina

// ---------------------------------------------------------------------------------------------
// Truth

namespace octshape::retina {
namespace {

using Clock = std::chrono::steady_clock;

// Clock-hour sector of an anatomical angle: k holds [30 k - 15, 30 k + 15) deg (the truth's
// own copy of the convention: the phantom shares no code with the analysis).
std::size_t clock_hour(double anatomical_deg) {
    return static_cast<std::size_t>(static_cast<int>((anatomical_deg + 15.0) / 30.0) % 12);
}

struct TruthPass {
    double cup = 0.0;
    double bmo = 0.0;
    double tv = 0.0;
    double av = 0.0;
    double bending = 0.0;
    double mrw_mean = 0.0;
    double mrw_mean_arclength = 0.0;
    double mrw_min = 0.0;
    double mrw_max = 0.0;
    double mrw_area = 0.0;
    std::array<double, 12> sector{};
    std::array<int, 12> sector_n{};
    std::vector<Eigen::Vector3d> bmo_points;
    std::vector<Eigen::Vector3d> mrw_points;
    std::vector<double> mrw;
    std::vector<double> anatomical;
};

// Break points in s where any region indicator or the smoothness of the integrand changes:
// kinks of the profile, rho(s) = 1 (the BMO), w(s) = 0 (the cup boundary).
std::vector<double> base_breaks(const OnhPhantomGeometry& g) {
    std::vector<double> b = g.kinks();
    for (double s : g.rho_roots(1.0)) b.push_back(s);
    for (double s : find_roots([&g](double s) { return g.w(s); }, 0.0, g.s_max(), 40000)) {
        b.push_back(s);
    }
    return b;
}

// Integral of w rho rho' over the s-segments (between break points in [0, hi]) whose midpoint
// satisfies `keep(rho, w)`: the signed-area volume per radian of phi, divided by a b.
template <typename Keep>
double volume_integral(const OnhPhantomGeometry& g,
                       const std::vector<double>& breaks,
                       double step,
                       Keep&& keep) {
    double sum = 0.0;
    for (std::size_t i = 0; i + 1 < breaks.size(); ++i) {
        const double mid = 0.5 * (breaks[i] + breaks[i + 1]);
        if (!keep(g.rho(mid), g.w(mid))) continue;
        gauss_legendre(breaks[i], breaks[i + 1], step,
                       [&](double s, double wt) { sum += wt * g.w(s) * g.rho(s) * g.drho(s); });
    }
    return sum;
}

// Closest point on the ILM to p (Eq. 8.21-8.22 on the true surface): coarse grid over (s, phi)
// in the window that can hold a point closer than the ILM point vertically above p, then
// pattern search from the best grid minima down to 1e-14 in the parameters.
std::pair<double, double> closest_point(const OnhPhantomGeometry& g,
                                        const Eigen::Vector3d& p,
                                        double phi0,
                                        double upper_bound,
                                        double step,
                                        double undercut) {
    const Eigen::Matrix2d& frame = g.frame();
    const Eigen::Vector2d c = g.bmo_centre();
    // The frame's columns are orthogonal (Rot diag(a, b)): its smallest singular value is b.
    const double b_min = std::min(frame.col(0).norm(), frame.col(1).norm());
    const double ratio = upper_bound / b_min;
    const double s_lo = std::max(0.0, 1.0 - ratio - undercut - step);
    const double s_hi = std::min(g.s_max(), 1.0 + ratio + step);
    const double half = ratio < 1.0 ? std::asin(ratio) + 2.0 * step : kPi;
    const int ns = std::max(2, static_cast<int>(std::ceil((s_hi - s_lo) / step)));
    const int np = std::max(2, static_cast<int>(std::ceil(2.0 * half / step)));
    std::vector<double> rs(static_cast<std::size_t>(ns + 1));
    std::vector<double> ws(static_cast<std::size_t>(ns + 1));
    for (int i = 0; i <= ns; ++i) {
        const double s = s_lo + (s_hi - s_lo) * i / ns;
        rs[static_cast<std::size_t>(i)] = g.rho(s);
        ws[static_cast<std::size_t>(i)] = g.w(s);
    }
    auto dist2_at = [&](double r, double wv, double phi) {
        const Eigen::Vector2d xy =
            c + frame * Eigen::Vector2d(r * std::cos(phi), r * std::sin(phi));
        const Eigen::Vector3d x(xy.x(), xy.y(), g.bm_height(xy.x(), xy.y()) + wv);
        return (x - p).squaredNorm();
    };
    auto dist2 = [&](double s, double phi) { return dist2_at(g.rho(s), g.w(s), phi); };
    const auto stride = static_cast<std::size_t>(np + 1);
    std::vector<double> grid(static_cast<std::size_t>(ns + 1) * stride);
    for (int j = 0; j <= np; ++j) {
        const double phi = phi0 - half + 2.0 * half * j / np;
        for (int i = 0; i <= ns; ++i) {
            const auto si = static_cast<std::size_t>(i);
            grid[si * stride + static_cast<std::size_t>(j)] = dist2_at(rs[si], ws[si], phi);
        }
    }
    // Grid local minima, best first.
    std::vector<std::pair<double, std::pair<int, int>>> minima;
    for (int i = 0; i <= ns; ++i) {
        for (int j = 0; j <= np; ++j) {
            const double v =
                grid[static_cast<std::size_t>(i) * stride + static_cast<std::size_t>(j)];
            bool is_min = true;
            for (int di = -1; di <= 1 && is_min; ++di) {
                for (int dj = -1; dj <= 1; ++dj) {
                    const int a = i + di;
                    const int b = j + dj;
                    if ((di == 0 && dj == 0) || a < 0 || a > ns || b < 0 || b > np) continue;
                    if (grid[static_cast<std::size_t>(a) * stride + static_cast<std::size_t>(b)] <
                        v) {
                        is_min = false;
                        break;
                    }
                }
            }
            if (is_min) minima.push_back({v, {i, j}});
        }
    }
    std::sort(minima.begin(), minima.end());
    if (minima.size() > 4) minima.resize(4);
    double best = std::numeric_limits<double>::infinity();
    std::pair<double, double> best_sp{0.0, phi0};
    const double hs0 = (s_hi - s_lo) / ns;
    const double hp0 = 2.0 * half / np;
    for (const auto& m : minima) {
        double s = s_lo + hs0 * m.second.first;
        double phi = phi0 - half + hp0 * m.second.second;
        double f = dist2(s, phi);
        double hs = hs0;
        double hp = hp0;
        for (int it = 0; it < 200000 && (hs > 1e-15 || hp > 1e-15); ++it) {
            double bs = s;
            double bp = phi;
            double bf = f;
            for (int di = -1; di <= 1; ++di) {
                for (int dj = -1; dj <= 1; ++dj) {
                    if (di == 0 && dj == 0) continue;
                    const double s2 = std::clamp(s + di * hs, 0.0, g.s_max());
                    const double p2 = phi + dj * hp;
                    const double f2 = dist2(s2, p2);
                    if (f2 < bf) {
                        bf = f2;
                        bs = s2;
                        bp = p2;
                    }
                }
            }
            if (bf < f) {
                s = bs;
                phi = bp;
                f = bf;
            } else {
                hs *= 0.5;
                hp *= 0.5;
            }
        }
        if (f < best) {
            best = f;
            best_sp = {s, phi};
        }
    }
    return best_sp;
}

TruthPass truth_pass(const OnhPhantomGeometry& g,
                     const OnhPhantomParams& params,
                     const OnhTruthOptions& o) {
    TruthPass t;
    const Eigen::Matrix2d& frame = g.frame();
    const double ab = std::fabs(frame.determinant());
    const std::vector<double> base = base_breaks(g);

    // Volumes, Eq. 8.8-8.9 with dA = a b rho rho'(s) ds dphi (signed).
    const auto all = breaks_in(base, 0.0, g.s_max());
    // 0 - x, not -x: a disc without a cup reports +0, not -0.
    t.cup = 0.0 - 2.0 * kPi * ab *
                      volume_integral(g, all, o.s_step, [](double, double w) { return w < 0.0; });
    const auto inner = breaks_in(base, 0.0, std::min(1.0, g.s_max()));
    t.bmo = 2.0 * kPi * ab * volume_integral(g, inner, o.s_step, [](double r, double w) {
                return r < 1.0 && w >= 0.0;
            });
    double tv = 0.0;
    double av = 0.0;
    for (int j = 0; j < o.phi_steps; ++j) {
        const double phi = 2.0 * kPi * j / o.phi_steps;
        const double rd =
            kDiscRadiusMm / (frame * Eigen::Vector2d(std::cos(phi), std::sin(phi))).norm();
        std::vector<double> b = base;
        for (double s : g.rho_roots(rd)) b.push_back(s);
        const auto br = breaks_in(b, 0.0, std::min(rd, g.s_max()));
        tv += volume_integral(g, br, o.s_step,
                              [rd](double r, double w) { return r < rd && w >= 0.0; });
        av += volume_integral(g, br, o.s_step,
                              [rd](double r, double w) { return r >= 1.0 && r < rd && w >= 0.0; });
    }
    t.tv = ab * tv * 2.0 * kPi / o.phi_steps;
    t.av = ab * av * 2.0 * kPi / o.phi_steps;

    // Bending energy: area-weighted normal tensor of the whole BMO region (Eq. 8.18-8.20 with
    // one tensor for the region, docs/algorithms/onh.md `bending_energy`); its trace is 1, E_b =
    // lambda2 + lambda3.
    Eigen::Matrix3d tensor = Eigen::Matrix3d::Zero();
    double area = 0.0;
    for (int j = 0; j < o.phi_steps; ++j) {
        const double phi = 2.0 * kPi * j / o.phi_steps;
        for (std::size_t i = 0; i + 1 < inner.size(); ++i) {
            if (!(g.rho(0.5 * (inner[i] + inner[i + 1])) < 1.0)) continue;
            gauss_legendre(inner[i], inner[i + 1], o.s_step, [&](double s, double wt) {
                const Eigen::Vector3d n = g.surface_ds(s, phi).cross(g.surface_dphi(s, phi));
                const double len = n.norm();
                if (len == 0.0) return;
                tensor += wt * n * n.transpose() / len;
                area += wt * len;
            });
        }
    }
    tensor /= area;
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(tensor);
    t.bending = eig.eigenvalues()(0) + eig.eigenvalues()(1);  // ascending order

    // BMO-MRW (Eq. 8.21-8.23): ellipse points uniform in the parameter angle.
    const phantom::GridFrame gf = phantom::grid_frame(layout_of(params));
    const int n = o.mrw_points;
    const auto above = g.crossings(1.0);
    const double upper = std::fabs(above.front());
    double sum = 0.0;
    double sum_arc = 0.0;
    double arc = 0.0;
    t.mrw_min = std::numeric_limits<double>::infinity();
    t.mrw_max = 0.0;
    for (int i = 0; i < n; ++i) {
        const double tt = 2.0 * kPi * i / n;
        const Eigen::Vector2d d = frame * Eigen::Vector2d(std::cos(tt), std::sin(tt));
        const Eigen::Vector2d xy = g.bmo_centre() + d;
        const Eigen::Vector3d p(xy.x(), xy.y(), g.bm_height(xy.x(), xy.y()));
        const auto [s, phi] =
            closest_point(g, p, tt, upper, o.mrw_search_step, params.profile.undercut);
        const Eigen::Vector3d q = g.surface(s, phi);
        const double m = (q - p).norm();
        const double speed = (frame * Eigen::Vector2d(-std::sin(tt), std::cos(tt))).norm();
        const double deg = gf.anatomical_angle_deg(d.x(), d.y());
        const std::size_t sector = clock_hour(deg);
        t.bmo_points.push_back(p);
        t.mrw_points.push_back(q);
        t.mrw.push_back(m);
        t.anatomical.push_back(deg);
        t.sector[sector] += m;
        t.sector_n[sector] += 1;
        sum += m;
        sum_arc += m * speed;
        arc += speed;
        t.mrw_min = std::min(t.mrw_min, m);
        t.mrw_max = std::max(t.mrw_max, m);
    }
    t.mrw_mean = sum / n;
    t.mrw_mean_arclength = sum_arc / arc;
    for (std::size_t k = 0; k < 12; ++k) {
        if (t.sector_n[k] > 0) t.sector[k] /= t.sector_n[k];
    }
    // Eq. 8.23: quad i = (p_i, p_i+1, q_i+1, q_i); area = |vector area| = |d1 x d2| / 2 with
    // the diagonals d1 = q_i+1 - p_i, d2 = q_i - p_i+1 (exact for a planar quad).
    for (int i = 0; i < n; ++i) {
        const auto a = static_cast<std::size_t>(i);
        const auto b = static_cast<std::size_t>((i + 1) % n);
        t.mrw_area +=
            0.5 *
            (t.mrw_points[b] - t.bmo_points[a]).cross(t.mrw_points[a] - t.bmo_points[b]).norm();
    }
    return t;
}

// In-plane BMO-MRW of a radial phantom (OnhInplaneTruth), the search along s with step
// `s_step`. Line k: grid points p(t) = C + t u, t in mm from the crossing; normalised
// v(t) = v0 + t du. The ILM curve in the line's plane is, for each s, the points of the line
// with |v(t)| = rho(s) (two branches, t-(s) and t+(s)), at height BM + w(s).
OnhInplaneTruth inplane_truth(const OnhPhantomGeometry& g, const OnhPhantomParams& params,
                              double s_step) {
    OnhInplaneTruth t;
    const phantom::GridFrame gf = phantom::grid_frame(layout_of(params));
    const Eigen::Vector2d cross = onh_radial_crossing(params);
    const Eigen::Vector2d centre = g.bmo_centre();
    const Eigen::Matrix2d frame_inv = g.frame().inverse();
    t.min_mm = std::numeric_limits<double>::infinity();
    double sum = 0.0;
    for (int k = 0; k < params.radial_lines; ++k) {
        const Eigen::Vector2d u = onh_radial_direction(params, k);
        const Eigen::Vector2d v0 = frame_inv * (cross - centre);
        const Eigen::Vector2d du = frame_inv * u;
        const double A = du.squaredNorm();
        const double B = v0.dot(du);
        // The line's parameters t where |v(t)| = r, branch sign -1 / +1 (NaN: no crossing).
        auto t_at = [&](double r, double sign) {
            const double disc = B * B - A * (v0.squaredNorm() - r * r);
            if (disc < 0.0) return std::numeric_limits<double>::quiet_NaN();
            return (-B + sign * std::sqrt(disc)) / A;
        };
        auto point = [&](double tt, double w) {
            const Eigen::Vector2d xy = cross + tt * u;
            return Eigen::Vector3d(xy.x(), xy.y(), g.bm_height(xy.x(), xy.y()) + w);
        };
        for (const double side : {-1.0, 1.0}) {
            const double tb = t_at(1.0, side);
            const Eigen::Vector3d p = point(tb, 0.0);
            auto dist2 = [&](double s, double sign) {
                const double tt = t_at(g.rho(s), sign);
                if (std::isnan(tt)) return std::numeric_limits<double>::infinity();
                return (point(tt, g.w(s)) - p).squaredNorm();
            };
            double best = std::numeric_limits<double>::infinity();
            double best_s = 0.0;
            double best_sign = side;
            const int n = static_cast<int>(std::ceil(g.s_max() / s_step));
            for (const double sign : {-1.0, 1.0}) {
                for (int i = 0; i <= n; ++i) {
                    const double s = std::min(g.s_max(), i * s_step);
                    const double d = dist2(s, sign);
                    if (d < best) {
                        best = d;
                        best_s = s;
                        best_sign = sign;
                    }
                }
            }
            // Golden section on the bracket of the best sample, down to 1e-13 in s.
            double lo = std::max(0.0, best_s - s_step);
            double hi = std::min(g.s_max(), best_s + s_step);
            const double gr = 0.5 * (std::sqrt(5.0) - 1.0);
            double x1 = hi - gr * (hi - lo);
            double x2 = lo + gr * (hi - lo);
            double f1 = dist2(x1, best_sign);
            double f2 = dist2(x2, best_sign);
            for (int it = 0; it < 200 && hi - lo > 1e-13; ++it) {
                if (f1 < f2) {
                    hi = x2;
                    x2 = x1;
                    f2 = f1;
                    x1 = hi - gr * (hi - lo);
                    f1 = dist2(x1, best_sign);
                } else {
                    lo = x1;
                    x1 = x2;
                    f1 = f2;
                    x2 = lo + gr * (hi - lo);
                    f2 = dist2(x2, best_sign);
                }
            }
            double s_opt = 0.5 * (lo + hi);
            if (!(dist2(s_opt, best_sign) <= best)) s_opt = best_s;
            const Eigen::Vector3d q = point(t_at(g.rho(s_opt), best_sign), g.w(s_opt));
            const double m = (q - p).norm();
            const double deg =
                gf.anatomical_angle_deg(p.x() - centre.x(), p.y() - centre.y());
            const std::size_t sector = clock_hour(deg);
            t.bmo_points_mm.push_back(p);
            t.mrw_points_mm.push_back(q);
            t.mrw_mm.push_back(m);
            t.anatomical_deg.push_back(deg);
            t.line.push_back(k);
            t.sector_mm[sector] += m;
            t.sector_points[sector] += 1;
            sum += m;
            t.min_mm = std::min(t.min_mm, m);
            t.max_mm = std::max(t.max_mm, m);
        }
    }
    t.mean_mm = sum / static_cast<double>(t.mrw_mm.size());
    for (std::size_t k = 0; k < 12; ++k) {
        if (t.sector_points[k] > 0) t.sector_mm[k] /= t.sector_points[k];
    }
    return t;
}

TruthAccuracy accuracy(std::string name, std::string method, double fine, double coarse) {
    TruthAccuracy a;
    a.name = std::move(name);
    a.method = std::move(method);
    a.value = fine;
    a.value_coarse = coarse;
    a.abs_change = std::fabs(fine - coarse);
    return a;
}

}  // namespace

void OnhTruthOptions::validate() const {
    require(finite_positive(s_step) && s_step <= 0.1, "truth s_step", "must be in (0, 0.1]");
    require(phi_steps >= 16 && phi_steps <= 1000000, "truth phi_steps", "must be >= 16");
    require(mrw_points >= 8 && mrw_points <= 100000, "truth mrw_points", "must be >= 8");
    require(finite_positive(mrw_search_step) && mrw_search_step <= 0.05, "truth mrw_search_step",
            "must be in (0, 0.05]");
}

OnhTruth compute_onh_truth(const OnhPhantomParams& params, const OnhTruthOptions& options) {
    const auto start = Clock::now();
    options.validate();
    const OnhPhantomGeometry g(params);
    OnhTruthOptions fine_options = options;
    fine_options.s_step /= 2.0;
    fine_options.phi_steps *= 2;
    fine_options.mrw_search_step /= 2.0;
    const TruthPass coarse = truth_pass(g, params, options);
    const TruthPass fine = truth_pass(g, params, fine_options);

    OnhTruth t;
    t.cup_volume_mm3 = fine.cup;
    t.has_cup = fine.cup > 0.0;
    t.conht_mm = g.crossings(0.0).front();
    t.bmo_volume_mm3 = fine.bmo;
    t.total_volume_mm3 = fine.tv;
    t.annular_volume_mm3 = fine.av;
    t.bmo_semi_axes_mm = {params.bmo_semi_major_mm, params.bmo_semi_minor_mm};
    t.bmo_area_mm2 = kPi * params.bmo_semi_major_mm * params.bmo_semi_minor_mm;  // Eq. 8.24
    t.bmo_orientation_deg = std::fmod(std::fmod(params.bmo_rotation_deg, 180.0) + 180.0, 180.0);
    const phantom::GridFrame gf = phantom::grid_frame(layout_of(params));
    const double th = params.bmo_rotation_deg * kPi / 180.0;
    t.bmo_orientation_anatomical_deg =
        std::fmod(gf.anatomical_angle_deg(std::cos(th), std::sin(th)), 180.0);
    t.bmo_centre_mm = {g.bmo_centre().x(), g.bmo_centre().y()};
    t.rpe_centre_height_mm = g.bm_height(g.bmo_centre().x(), g.bmo_centre().y());
    t.mrw_mean_mm = fine.mrw_mean;
    t.mrw_mean_arclength_mm = fine.mrw_mean_arclength;
    t.mrw_min_mm = fine.mrw_min;
    t.mrw_max_mm = fine.mrw_max;
    t.mrw_sector_mm = fine.sector;
    t.mrw_sector_points = fine.sector_n;
    t.mrw_area_mm2 = fine.mrw_area;
    t.bending_energy = fine.bending;
    t.bmo_points_mm = fine.bmo_points;
    t.mrw_points_mm = fine.mrw_points;
    t.mrw_mm = fine.mrw;
    t.bmo_anatomical_deg = fine.anatomical;

    const std::string gl =
        "composite 8-point Gauss-Legendre in s between the break points "
        "(profile kinks, rho(s) = 1, rho(s) = disc radius, w(s) = 0)";
    const std::string vol =
        "integral of h dA with signed projected area dA = a b rho rho'(s) "
        "ds dphi (Eq. 8.8-8.9); ";
    t.accuracy.push_back(accuracy("cup_volume_mm3", vol + "h < 0 anywhere; phi exact (2 pi); " + gl,
                                  fine.cup, coarse.cup));
    t.accuracy.push_back(accuracy(
        "bmo_volume_mm3", vol + "rho < 1, h >= 0; phi exact (2 pi); " + gl, fine.bmo, coarse.bmo));
    t.accuracy.push_back(accuracy("total_volume_mm3",
                                  vol + "inside the 1.5 mm disc, h >= 0; trapezoid in phi; " + gl,
                                  fine.tv, coarse.tv));
    t.accuracy.push_back(
        accuracy("annular_volume_mm3",
                 vol + "inside the 1.5 mm disc, rho >= 1, h >= 0; trapezoid in phi; " + gl, fine.av,
                 coarse.av));
    t.accuracy.push_back(
        accuracy("bending_energy",
                 "1 - largest eigenvalue of (1/A) integral n n^T dA over the ILM with rho(s) < 1, "
                 "dA = |X_s x X_phi| ds dphi; trapezoid in phi, " +
                     gl,
                 fine.bending, coarse.bending));
    t.accuracy.push_back(accuracy(
        "mrw_mean_mm",
        "closest point on the true ILM: coarse (s, phi) grid over the window that can beat the "
        "ILM point above the BMO point, pattern search from the 4 best grid minima",
        fine.mrw_mean, coarse.mrw_mean));
    t.accuracy.push_back(accuracy("mrw_mean_arclength_mm", "as mrw_mean_mm, weighted by |dP/dt|",
                                  fine.mrw_mean_arclength, coarse.mrw_mean_arclength));
    double max_point = 0.0;
    for (std::size_t i = 0; i < fine.mrw.size(); ++i) {
        max_point = std::max(max_point, std::fabs(fine.mrw[i] - coarse.mrw[i]));
    }
    TruthAccuracy per_point =
        accuracy("mrw_mm (largest per-point change)", "as mrw_mean_mm, each BMO point",
                 fine.mrw_max, coarse.mrw_max);
    per_point.abs_change = max_point;
    t.accuracy.push_back(per_point);
    t.accuracy.push_back(accuracy("mrw_area_mm2",
                                  "Eq. 8.23: sum of quad vector-area norms between BMO points "
                                  "and their closest ILM points",
                                  fine.mrw_area, coarse.mrw_area));
    t.accuracy.push_back(accuracy("conht_mm", "closed form: w at the top crossing of rho = 0",
                                  t.conht_mm, t.conht_mm));
    t.accuracy.push_back(
        accuracy("bmo_area_mm2", "closed form pi a b (Eq. 8.24)", t.bmo_area_mm2, t.bmo_area_mm2));
    if (params.radial) {
        // Search step 1e-4 in s (0.1 um of normalised radius ~ 0.08 um); the change with the
        // step doubled bounds the search error.
        t.has_inplane = true;
        t.inplane = inplane_truth(g, params, 1e-4);
        const OnhInplaneTruth coarse_in = inplane_truth(g, params, 2e-4);
        for (std::size_t i = 0; i < t.inplane.mrw_mm.size(); ++i) {
            t.inplane.abs_change_mm = std::max(
                t.inplane.abs_change_mm, std::fabs(t.inplane.mrw_mm[i] - coarse_in.mrw_mm[i]));
        }
        TruthAccuracy a = accuracy(
            "mrw_inplane_mean_mm",
            "in each radial line's vertical plane: where the line crosses the true BMO ellipse "
            "(two points) to the closest point of the true ILM curve in that plane; dense search "
            "in s on both branches of the curve, golden-section refinement",
            t.inplane.mean_mm, coarse_in.mean_mm);
        t.accuracy.push_back(a);
    }
    t.seconds = std::chrono::duration<double>(Clock::now() - start).count();
    return t;
}

}  // namespace octshape::retina

// ---------------------------------------------------------------------------------------------
// Pixels, device lines, SLO

namespace octshape::retina {
namespace {

// Linear reflectance of the neural tissue inside the BMO (and wherever a column meets the ILM
// more than once): a bright nerve-fibre surface fading with the depth e below it, over a dim
// bulk that, below the BM level, is the lamina region: faintly striated and fading with depth
// like the choroid beside it.
double neural_reflectance(double e_mm, double below_bm_mm) {
    const double surface = 0.26 * std::exp(-e_mm / 0.08);
    if (below_bm_mm <= 0.0) return 0.06 + surface;
    const double lamina = 0.06 * std::exp(-below_bm_mm / 0.15) *
                          (1.0 + 0.25 * std::sin(2.0 * kPi * below_bm_mm / 0.04));
    return surface + lamina;
}

struct Column {
    double r = 0.0;             // normalised radius
    double dist_bmo_mm = 0.0;   // distance outside the BMO along the ray (0 inside)
    double bm_z = 0.0;          // BM height
    std::vector<double> ilm_z;  // ILM crossings, descending (absolute heights)
};

Column column_at(const OnhPhantomGeometry& g, double x, double y) {
    Column c;
    const Eigen::Vector2d v = g.normalised(x, y);
    c.r = v.norm();
    if (c.r > 1.0) {
        c.dist_bmo_mm = (c.r - 1.0) * (g.frame() * (v / c.r)).norm();
    }
    c.bm_z = g.bm_height(x, y);
    c.ilm_z = g.ilm_heights(x, y);
    return c;
}

// Columns crossed once, outside the BMO: the layered retina of phantom_common with the layers
// adapted to the disc (the nerve-fibre layer takes most of the thickness near the BMO, the
// outer retina tapers towards it).
void layered_column(const Column& c, double scale_z, std::span<float> out) {
    phantom::RetinaLayers layers;
    const double near = std::exp(-c.dist_bmo_mm / 0.6);
    layers.outer_mm = 0.20 * (1.0 - std::exp(-(c.dist_bmo_mm + 0.03) / 0.12));
    const double rnfl = 0.2 + 0.6 * near;
    const double scale = (1.0 - rnfl) / 0.8;
    layers.inner_fractions = {rnfl, 0.3 * scale, 0.2 * scale, 0.18 * scale, 0.12 * scale};
    const double ilm_px = -c.ilm_z.front() / scale_z;
    const double bm_px = -c.bm_z / scale_z;
    phantom::layered_retina_column(phantom::retina_boundaries(ilm_px, bm_px, scale_z, layers),
                                   scale_z, layers, out);
}

// Any other column: exact tissue fraction of every pixel from the crossings (partial volume),
// neural reflectance inside, choroid below the BM outside the BMO.
void general_column(const Column& c, double scale_z, std::span<float> out) {
    const phantom::RetinaLayers layers;
    // Tissue intervals (lo, hi) in z: below every odd-numbered crossing down to the next one.
    std::vector<std::pair<double, double>> tissue;
    for (std::size_t k = 0; k < c.ilm_z.size(); k += 2) {
        const double hi = c.ilm_z[k];
        const double lo =
            k + 1 < c.ilm_z.size() ? c.ilm_z[k + 1] : -std::numeric_limits<double>::infinity();
        tissue.emplace_back(lo, hi);
    }
    for (std::size_t p = 0; p < out.size(); ++p) {
        const double top = -(static_cast<double>(p) - 0.5) * scale_z;
        const double bottom = top - scale_z;
        double inside = 0.0;
        double best = 0.0;
        double e = 0.0;
        double z_mid = 0.5 * (top + bottom);
        for (const auto& [lo, hi] : tissue) {
            const double a = std::max(lo, bottom);
            const double b = std::min(hi, top);
            if (b <= a) continue;
            inside += b - a;
            if (b - a > best) {
                best = b - a;
                z_mid = 0.5 * (a + b);
                e = hi - z_mid;
            }
        }
        const double alpha = inside / scale_z;
        double tissue_value = 0.0;
        if (alpha > 0.0) {
            const double below_bm = c.bm_z - z_mid;
            if (c.r >= 1.0 && below_bm > 0.0) {
                tissue_value = layers.choroid * std::exp(-below_bm / layers.choroid_decay_mm);
            } else {
                tissue_value = neural_reflectance(e, below_bm);
            }
        }
        out[p] = static_cast<float>(alpha * tissue_value + (1.0 - alpha) * layers.vitreous);
    }
}

// A vessel: a polyline in grid mm and its bounding box grown by the drawing reach.
struct Vessel {
    std::vector<Eigen::Vector2d> line;
    Eigen::Vector2d lo = Eigen::Vector2d::Zero();
    Eigen::Vector2d hi = Eigen::Vector2d::Zero();
};
constexpr double kVesselSigmaMm = 0.035;

std::vector<Vessel> vessel_lines(const OnhPhantomGeometry& g, const phantom::GridFrame& gf) {
    // (start angle, turn in deg per mm): anatomical angles, 0 nasal, 90 superior. The
    // superior and inferior arcades curve temporally (towards 180 deg), nasal ones less.
    const std::array<std::pair<double, double>, 8> spec = {{{105.0, 16.0},
                                                            {255.0, -16.0},
                                                            {135.0, 8.0},
                                                            {225.0, -8.0},
                                                            {60.0, -6.0},
                                                            {300.0, 6.0},
                                                            {15.0, -4.0},
                                                            {345.0, 4.0}}};
    std::vector<Vessel> vessels;
    for (const auto& [a0, turn] : spec) {
        Vessel v;
        for (int i = 0; i <= 40; ++i) {
            const double t = 0.1 * i;  // mm along the vessel
            v.line.push_back(g.bmo_centre() + (0.3 + t) * gf.grid_direction(a0 + turn * t));
        }
        v.lo = v.hi = v.line.front();
        for (const auto& q : v.line) {
            v.lo = v.lo.cwiseMin(q);
            v.hi = v.hi.cwiseMax(q);
        }
        v.lo.array() -= 5.0 * kVesselSigmaMm;
        v.hi.array() += 5.0 * kVesselSigmaMm;
        vessels.push_back(std::move(v));
    }
    return vessels;
}

// A plausible fundus picture: vignetted background, the disc with its rim and pallor, the
// fovea temporal to it, and vessels leaving the disc.
double slo_brightness(const OnhPhantomGeometry& g,
                      const OnhPhantomParams& params,
                      const phantom::GridFrame& gf,
                      const Eigen::Matrix2d& slo_to_grid,
                      const std::vector<Vessel>& vessels,
                      double x_slo,
                      double y_slo) {
    const Eigen::Vector2d grid = slo_to_grid * (Eigen::Vector2d(x_slo, y_slo) - gf.origin_slo_mm);
    const Eigen::Vector2d c = g.bmo_centre();
    const double side = gf.slo_scale_mm * 256.0;
    const Eigen::Vector2d slo_centre(side / 2, side / 2);
    const double rr = (Eigen::Vector2d(x_slo, y_slo) - slo_centre).norm() / (side / 2);
    double v = 0.45 * (1.0 - 0.35 * rr * rr);
    const double rn = g.normalised(grid.x(), grid.y()).norm();
    v += 0.30 / (1.0 + std::exp((rn - 1.1) / 0.05));  // disc
    if (params.profile.cup_depth_mm > 0.0 && params.profile.swelling_mm == 0.0) {
        v += 0.15 / (1.0 + std::exp((rn - params.profile.cup_radius) / 0.05));  // pallor
    }
    const Eigen::Vector2d fovea = c + 4.5 * gf.grid_direction(180.0);
    v -= 0.18 * std::exp(-(grid - fovea).squaredNorm() / (2.0 * 0.6 * 0.6));
    double darkest = 0.0;
    for (const Vessel& vs : vessels) {
        if ((grid.array() < vs.lo.array()).any() || (grid.array() > vs.hi.array()).any()) {
            continue;
        }
        for (std::size_t i = 0; i + 1 < vs.line.size(); ++i) {
            const Eigen::Vector2d ab = vs.line[i + 1] - vs.line[i];
            const double t = std::clamp((grid - vs.line[i]).dot(ab) / ab.squaredNorm(), 0.0, 1.0);
            const double d = (grid - (vs.line[i] + t * ab)).norm();
            darkest = std::max(darkest, std::exp(-d * d / (2.0 * kVesselSigmaMm * kVesselSigmaMm)));
        }
    }
    return v * (1.0 - 0.45 * darkest);
}

// The frame of a radial phantom: the volume's SLO (so the fundus picture and the anatomical
// frame are the volume's), radial_lines B-scans of num_ascans A-scans, each placed on the SLO
// from the crossing along its direction; no B-scan Distance.
io::Scan radial_scan_frame(const OnhPhantomParams& p, const phantom::VolumeLayout& volume) {
    phantom::VolumeLayout l = volume;
    l.pattern = io::ScanPattern::kRadial;
    l.num_bscans = p.radial_lines;
    l.scale_x_mm = p.line_length_mm / (p.num_ascans - 1);
    io::Scan s = phantom::make_scan_frame(l);
    const phantom::GridFrame gf = phantom::grid_frame(volume);
    s.meta.scale_x_slo_mm = gf.slo_scale_mm;
    s.meta.scale_y_slo_mm = gf.slo_scale_mm;
    s.meta.distance_mm = 0.0;
    const Eigen::Vector2d c = onh_radial_crossing(p);
    for (int k = 0; k < p.radial_lines; ++k) {
        const Eigen::Vector2d u = onh_radial_direction(p, k);
        const Eigen::Vector2d start = gf.to_slo(c - 0.5 * p.line_length_mm * u);
        const Eigen::Vector2d end = gf.to_slo(c + 0.5 * p.line_length_mm * u);
        io::BScan& b = s.bscans[static_cast<std::size_t>(k)];
        b.start_x_mm = start.x();
        b.start_y_mm = start.y();
        b.end_x_mm = end.x();
        b.end_y_mm = end.y();
    }
    return s;
}

}  // namespace

phantom::AcquisitionShifts onh_acquisition_shifts(const OnhPhantomParams& params) {
    const OnhPhantomGeometry g(params);
    const int nb = params.radial ? params.radial_lines : params.num_bscans;
    const double sx =
        params.radial ? params.line_length_mm / (params.num_ascans - 1) : g.scale_x_mm();
    return phantom::acquisition_shifts(params.artefacts, nb, g.scale_z_mm(), sx, params.radial,
                                       params.seed);
}

io::Scan render_onh_scan(const OnhPhantomParams& params) {
    const OnhPhantomGeometry g(params);
    const phantom::VolumeLayout layout = layout_of(params);
    io::Scan scan =
        params.radial ? radial_scan_frame(params, layout) : phantom::make_scan_frame(layout);
    const int nb = scan.num_bscans();
    // Every A-scan's grid position: the same continuous eye for volumes and radial scans, where
    // the moving eye puts it (phantom::acquired_points; the still grid when still).
    const phantom::AcquisitionShifts shifts = onh_acquisition_shifts(params);
    const std::vector<Eigen::Vector2d> points =
        phantom::acquired_points(onh_sample_points(params), params.num_ascans, shifts);
    scan.meta.prog_id = std::string("octshape ") + kVersion + " phantom onh";
    scan.notes.push_back("synthetic ONH phantom (" + to_string(params.shape) + ")");
    const double sz = g.scale_z_mm();
    const int nx = params.num_ascans;

    // Every column first: the geometry must fit the image before any pixel is drawn.
    std::vector<std::vector<Column>> columns(static_cast<std::size_t>(nb));
    for (int b = 0; b < nb; ++b) {
        auto& row = columns[static_cast<std::size_t>(b)];
        row.reserve(static_cast<std::size_t>(nx));
        // The eye moved axial_px[b] deeper (heights are -depth): every height of the column,
        // after the still eye was checked to fit (the moved retina's lines are checked by
        // apply_acquisition_artefacts).
        const double dz_mm = shifts.axial_px[static_cast<std::size_t>(b)] * sz;
        for (int a = 0; a < nx; ++a) {
            const Eigen::Vector2d& pt = points[static_cast<std::size_t>(b) *
                                                   static_cast<std::size_t>(nx) +
                                               static_cast<std::size_t>(a)];
            Column c = column_at(g, pt.x(), pt.y());
            const double top_px = -c.ilm_z.front() / sz;
            const double deepest_px = -std::min(c.ilm_z.back(), c.bm_z) / sz;
            require(top_px >= 1.0, "depth",
                    "too small: the ILM rises above the top of the image (B-scan " +
                        std::to_string(b) + ", A-scan " + std::to_string(a) +
                        "); increase depth or bm_centre_depth_fraction");
            require(deepest_px <= params.depth_px - 20.0, "depth",
                    "too small: the BM or cup floor is within 20 px of the image bottom (B-scan " +
                        std::to_string(b) + ", A-scan " + std::to_string(a) +
                        "); increase depth or decrease bm_centre_depth_fraction");
            if (dz_mm != 0.0) {
                for (double& z : c.ilm_z) z -= dz_mm;
                c.bm_z -= dz_mm;
            }
            row.push_back(std::move(c));
        }
    }

    const auto nan = std::numeric_limits<float>::quiet_NaN();
    phantom::SpeckleParams speckle;
    speckle.looks = params.speckle_looks;
    speckle.axial_half_width_px = params.speckle_axial_half_width_px;
    speckle.lateral_half_width_px = params.speckle_lateral_half_width_px;
    for (int b = 0; b < nb; ++b) {
        const auto& row = columns[static_cast<std::size_t>(b)];
        io::BScan& bs = scan.bscans[static_cast<std::size_t>(b)];
        for (int a = 0; a < nx; ++a) {
            const Column& c = row[static_cast<std::size_t>(a)];
            const auto ai = static_cast<std::size_t>(a);
            // Device lines: the first tissue from the top (graph envelope) and BM outside the
            // opening only.
            bs.seg[static_cast<std::size_t>(io::Layer::kILM)][ai] =
                static_cast<float>(-c.ilm_z.front() / sz);
            bs.seg[static_cast<std::size_t>(io::Layer::kBM)][ai] =
                c.r < 1.0 ? nan : static_cast<float>(-c.bm_z / sz);
        }
        phantom::render_bscan(
            bs, nx, params.depth_px,
            [&](int a, std::span<float> out) {
                const Column& c = row[static_cast<std::size_t>(a)];
                if (c.r >= 1.0 && c.ilm_z.size() == 1) {
                    layered_column(c, sz, out);
                } else {
                    general_column(c, sz, out);
                }
            },
            speckle, params.seed, static_cast<std::uint64_t>(b));
    }
    scan.pixels_loaded = true;

    const phantom::GridFrame gf = phantom::grid_frame(layout);
    const auto vessels = vessel_lines(g, gf);
    if (params.artefacts.any()) {
        // The SLO's vessels in the B-scans, 150 um (the arcades) down to 60 um wide; faults
        // farther than 1.6 mm from the BMO centre (outside every volume's disc).
        constexpr std::array<double, 8> kWidthMm = {0.150, 0.140, 0.110, 0.100,
                                                    0.090, 0.080, 0.070, 0.060};
        std::vector<phantom::VesselPath> paths;
        for (std::size_t v = 0; v < vessels.size(); ++v) {
            paths.push_back({vessels[v].line, kWidthMm[v % kWidthMm.size()]});
        }
        phantom::apply_acquisition_artefacts(
            scan, points, paths, params.artefacts, static_cast<int>(io::Layer::kILM), static_cast<int>(io::Layer::kBM), g.bmo_centre(),
            1.6);
    }
    const Eigen::Matrix2d slo_to_grid = gf.grid_to_slo.inverse();
    phantom::render_slo(
        scan,
        [&](double x, double y) {
            return slo_brightness(g, params, gf, slo_to_grid, vessels, x, y);
        },
        params.seed);
    return scan;
}

OnhPhantom make_onh_phantom(const OnhPhantomParams& params, const OnhTruthOptions& truth_options) {
    OnhPhantom p;
    p.scan = render_onh_scan(params);
    p.truth = compute_onh_truth(params, truth_options);
    return p;
}

namespace {

// The frame, angles and definitions the truth values follow.
nlohmann::json onh_truth_conventions() {
    using nlohmann::json;
    json j;
    j["conventions"] = {
        {"frame",
         "grid mm: x = A-scan index * ScaleX, y = B-scan index * Distance "
         "(B-scan 0 most inferior), height z = -depth (pixel row * ScaleZ)"},
        {"angles", "anatomical: 0 deg = nasal, 90 deg = superior, for both eyes"},
        {"volumes",
         "integral of h = ILM - RPE height with signed projected area (Eq. 8.8-8.9); "
         "cup: h < 0 (reported positive); bmo: inside the BMO ellipse, h >= 0; total: "
         "inside the 1.5 mm disc around the BMO centre, h >= 0; annular: inside the "
         "disc and outside the ellipse, h >= 0"},
        {"conht",
         "height of the first ILM crossing from the top of the vertical line through "
         "the BMO centre minus the RPE height there"},
        {"rpe",
         "the quadratic BM surface, also inside the opening (what a biharmonic fill "
         "reproduces exactly)"},
        {"mrw",
         "distance from each BMO point (ellipse point, z = BM height) to the closest "
         "point on the true ILM surface; points uniform in the ellipse parameter angle"},
        {"mrw_sectors",
         "12 clock-hour sectors centred on anatomical 0, 30, ..., 330 deg; sector "
         "k holds the BMO points with angle in [30k - 15, 30k + 15)"},
        {"bending_energy",
         "lambda2 + lambda3 (= 1 - lambda1) of the area-weighted normal "
         "tensor of the whole ILM region inside the BMO (cup included)"}};
    return j["conventions"];
}

// The phantom's parameters as written in the truth file (the radial pattern's only when radial,
// so that a volume's truth file stays bit for bit as before).
nlohmann::json onh_options_json(const OnhPhantomParams& params, const OnhPhantomGeometry& g) {
    using nlohmann::json;
    const OnhProfileParams& pr = params.profile;
    json j;
    j["options"] = {{"shape", to_string(params.shape)},
                    {"eye", std::string(io::to_string(params.eye))},
                    {"seed", params.seed},
                    {"bscans", params.num_bscans},
                    {"ascans", params.num_ascans},
                    {"depth_px", params.depth_px},
                    {"field_mm", params.field_mm},
                    {"scale_x_mm", g.scale_x_mm()},
                    {"distance_mm", g.distance_mm()},
                    {"scale_z_mm", params.scale_z_mm},
                    {"bm_centre_depth_fraction", params.bm_centre_depth_fraction},
                    {"bmo_offset_mm", {params.bmo_offset_x_mm, params.bmo_offset_y_mm}},
                    {"bmo_semi_axes_mm", {params.bmo_semi_major_mm, params.bmo_semi_minor_mm}},
                    {"bmo_rotation_deg", params.bmo_rotation_deg},
                    {"eye_radius_mm", params.eye_radius_mm},
                    {"tilt", {params.tilt_x, params.tilt_y}},
                    {"speckle_looks", params.speckle_looks},
                    {"profile",
                     {{"retina_thickness_mm", pr.retina_thickness_mm},
                      {"rim_height_mm", pr.rim_height_mm},
                      {"rim_radius", pr.rim_radius},
                      {"swelling_mm", pr.swelling_mm},
                      {"swelling_width", pr.swelling_width},
                      {"cup_depth_mm", pr.cup_depth_mm},
                      {"cup_radius", pr.cup_radius},
                      {"cup_exponent", pr.cup_exponent},
                      {"cup_profile", to_string(pr.cup_profile)},
                      {"undercut", pr.undercut},
                      {"undercut_height_mm", pr.undercut_height_mm},
                      {"undercut_halfwidth_mm", pr.undercut_halfwidth_mm}}}};
    if (params.speckle_axial_half_width_px > 0.0 || params.speckle_lateral_half_width_px > 0.0) {
        // only then (a phantom without a grain keeps its truth file)
        j["options"]["speckle_axial_half_width_px"] = params.speckle_axial_half_width_px;
        j["options"]["speckle_lateral_half_width_px"] = params.speckle_lateral_half_width_px;
    }
    if (params.radial) {  // only then (a volume's truth file stays bit for bit as before)
        j["options"]["pattern"] = "radial";
        const Eigen::Vector2d c = onh_radial_crossing(params);
        j["options"]["radial_lines"] = params.radial_lines;
        j["options"]["line_length_mm"] = params.line_length_mm;
        j["options"]["crossing_offset_um"] = params.crossing_offset_um;
        if (params.crossing_offset_y_um != 0.0) {  // only then (older truth files unchanged)
            j["options"]["crossing_offset_y_um"] = params.crossing_offset_y_um;
        }
        // The truth's grid frame is the volume's of the same parameters; the radial scan
        // itself has no grid: the lines' crossing places it.
        j["options"]["crossing_mm"] = {c.x(), c.y()};
        j["options"]["line_ascan_spacing_mm"] = params.line_length_mm / (params.num_ascans - 1);
    }
    return j["options"];
}

// The acquisition artefacts and the true per-B-scan shifts (written only for a phantom with
// artefacts, so that a still phantom's truth file is unchanged).
nlohmann::json onh_acquisition_json(const OnhPhantomParams& params, const OnhPhantomGeometry& g) {
    using nlohmann::json;
    json j;
    const phantom::AcquisitionArtefacts& a = params.artefacts;
    const phantom::AcquisitionShifts sh = onh_acquisition_shifts(params);
    json axial_um = json::array();
    json lateral_um = json::array();
    for (std::size_t b = 0; b < sh.axial_px.size(); ++b) {
        axial_um.push_back(sh.axial_px[b] * g.scale_z_mm() * 1000.0);
        lateral_um.push_back(sh.lateral_px[b] * (params.radial ? 0.0 : g.scale_x_mm()) *
                             1000.0);
    }
    j["acquisition"] = {
        {"motion_sd_um", a.motion_sd_um},
        {"lateral_jitter_um", a.lateral_jitter_um},
        {"vessel_shadows", a.vessel_shadows},
        {"cleft", a.cleft},
        {"segmentation_faults", a.segmentation_faults},
        {"axial_shift_um", axial_um},
        {"lateral_shift_um", lateral_um},
        {"note",
         "the acquisition's artefacts, not the eye's: B-scan b's pixels and device lines lie "
         "axial_shift_um[b] deeper (and lateral_shift_um[b] towards higher A-scans) than the "
         "eye; the truth is that of the still eye"}};
    return j["acquisition"];
}

// The truth values, their accuracy and the BMO points.
void add_onh_truth_values(const OnhTruth& truth, nlohmann::json& j) {
    using nlohmann::json;
    json sectors = json::object();
    for (std::size_t k = 0; k < 12; ++k) {
        sectors[std::to_string(30 * k)] =
            truth.mrw_sector_points[k] > 0 ? json(truth.mrw_sector_mm[k]) : json(nullptr);
    }
    j["truth"] = {{"has_cup", truth.has_cup},
                  {"cup_volume_mm3", truth.cup_volume_mm3},
                  {"conht_mm", truth.conht_mm},
                  {"bmo_volume_mm3", truth.bmo_volume_mm3},
                  {"total_volume_mm3", truth.total_volume_mm3},
                  {"annular_volume_mm3", truth.annular_volume_mm3},
                  {"bmo_area_mm2", truth.bmo_area_mm2},
                  {"bmo_semi_axes_mm", truth.bmo_semi_axes_mm},
                  {"bmo_orientation_deg", truth.bmo_orientation_deg},
                  {"bmo_orientation_anatomical_deg", truth.bmo_orientation_anatomical_deg},
                  {"bmo_centre_mm", truth.bmo_centre_mm},
                  {"rpe_centre_height_mm", truth.rpe_centre_height_mm},
                  {"mrw_mean_mm", truth.mrw_mean_mm},
                  {"mrw_mean_arclength_mm", truth.mrw_mean_arclength_mm},
                  {"mrw_min_mm", truth.mrw_min_mm},
                  {"mrw_max_mm", truth.mrw_max_mm},
                  {"mrw_sector_mm", sectors},
                  {"mrw_area_mm2", truth.mrw_area_mm2},
                  {"bending_energy", truth.bending_energy}};
    json acc = json::object();
    for (const TruthAccuracy& a : truth.accuracy) {
        acc[a.name] = {{"method", a.method},
                       {"value", a.value},
                       {"value_with_double_steps", a.value_coarse},
                       {"abs_change", a.abs_change}};
    }
    j["accuracy"] = acc;
    json points = json::array();
    for (std::size_t i = 0; i < truth.bmo_points_mm.size(); ++i) {
        const auto& p = truth.bmo_points_mm[i];
        const auto& q = truth.mrw_points_mm[i];
        points.push_back({{"bmo_mm", {p.x(), p.y(), p.z()}},
                          {"mrw_point_mm", {q.x(), q.y(), q.z()}},
                          {"mrw_mm", truth.mrw_mm[i]},
                          {"anatomical_deg", truth.bmo_anatomical_deg[i]}});
    }
    j["bmo_points"] = points;
}

// Radial scans: the in-plane minimum rim width (per B-scan plane).
void add_onh_inplane_truth(const OnhInplaneTruth& in, nlohmann::json& j) {
    using nlohmann::json;
    json isec = json::object();
    json ipts = json::array();
    for (std::size_t k = 0; k < 12; ++k) {
        isec[std::to_string(30 * k)] =
            in.sector_points[k] > 0 ? json(in.sector_mm[k]) : json(nullptr);
    }
    for (std::size_t i = 0; i < in.mrw_mm.size(); ++i) {
        const auto& p = in.bmo_points_mm[i];
        const auto& q = in.mrw_points_mm[i];
        ipts.push_back({{"bscan", in.line[i]},
                        {"bmo_mm", {p.x(), p.y(), p.z()}},
                        {"mrw_point_mm", {q.x(), q.y(), q.z()}},
                        {"mrw_mm", in.mrw_mm[i]},
                        {"anatomical_deg", in.anatomical_deg[i]}});
    }
    j["truth"]["mrw_inplane_mean_mm"] = in.mean_mm;
    j["truth"]["mrw_inplane_min_mm"] = in.min_mm;
    j["truth"]["mrw_inplane_max_mm"] = in.max_mm;
    j["truth"]["mrw_inplane_sector_mm"] = isec;
    j["conventions"]["mrw_inplane"] =
        "radial scans: in each B-scan's vertical plane, from the two points where its line "
        "crosses the BMO ellipse (z = BM height) to the closest point of the true ILM curve "
        "in that plane; sectors as mrw_sectors, by the BMO point's angle about the BMO centre";
    j["inplane_bmo_points"] = ipts;
    j["accuracy"]["mrw_inplane_mean_mm"]["largest_per_point_change"] = in.abs_change_mm;
}

}  // namespace

nlohmann::json onh_truth_to_json(const OnhPhantomParams& params,
                                 const OnhTruthOptions& options,
                                 const OnhTruth& truth) {
    using nlohmann::json;
    const OnhPhantomGeometry g(params);
    json j;
    j["generator"] = "octshape phantom onh";
    // The version only (docs/outputs.md, "Provenance"): the documented command reproduces the
    // file bit for bit from any revision of it.
    j["provenance"] = {{"version", kVersion}};
    j["conventions"] = onh_truth_conventions();
    j["options"] = onh_options_json(params, g);
    if (params.artefacts.any()) j["acquisition"] = onh_acquisition_json(params, g);
    j["truth_options"] = {{"s_step", options.s_step},
                          {"phi_steps", options.phi_steps},
                          {"mrw_points", options.mrw_points},
                          {"mrw_search_step", options.mrw_search_step}};
    add_onh_truth_values(truth, j);
    if (truth.has_inplane) add_onh_inplane_truth(truth.inplane, j);
    return j;  // no timings: the same options give the same file
}

}  // namespace octshape::retina
