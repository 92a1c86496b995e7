#include "octshape/retina/phantom_macula.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <numeric>
#include <stdexcept>

#include <Eigen/Eigenvalues>

#include "octshape/error.h"
#include "octshape/version.h"

namespace octshape::retina {
namespace {

using V2 = Eigen::Vector2d;
using Cubic = std::array<V2, 4>;

constexpr double kPi = std::numbers::pi;
constexpr double kDeg = 180.0 / kPi;
constexpr double kFieldWidthMm = 767 * 0.01169;  // 768 A-scans at ScaleX 0.01169 mm
constexpr double kFieldHeightMm = 7.5;          // 61 B-scans at 0.125 mm
constexpr double kEps = std::numeric_limits<double>::epsilon();

void require(bool ok, const std::string& field, const std::string& why) {
    if (!ok) throw UsageError("macula phantom: " + field + " " + why);
}

// ---- cubic Bezier --------------------------------------------------------------------------

V2 bez(const Cubic& p, double t) {
    const double u = 1.0 - t;
    return u * u * u * p[0] + 3 * u * u * t * p[1] + 3 * u * t * t * p[2] + t * t * t * p[3];
}

V2 bez_d(const Cubic& p, double t) {
    const double u = 1.0 - t;
    return 3 * (u * u * (p[1] - p[0]) + 2 * u * t * (p[2] - p[1]) + t * t * (p[3] - p[2]));
}

// t in [0, 1] with x(t) = r, for a curve whose x is strictly increasing. Safeguarded Newton:
// converges to the last bit (the bracket shrinks to neighbouring doubles).
double solve_x(const Cubic& p, double r) {
    if (r <= p[0].x()) return 0.0;
    if (r >= p[3].x()) return 1.0;
    double lo = 0.0;
    double hi = 1.0;
    double t = (r - p[0].x()) / (p[3].x() - p[0].x());
    for (int it = 0; it < 200; ++it) {
        const double f = bez(p, t).x() - r;
        if (f == 0.0) return t;
        if (f > 0.0) {
            hi = t;
        } else {
            lo = t;
        }
        double next = t - f / bez_d(p, t).x();
        if (!(next > lo && next < hi)) next = 0.5 * (lo + hi);
        if (next == t || hi - lo <= 2 * kEps) return next;
        t = next;
    }
    return t;
}

// Integral over [t0, t1] of y x dx/dt: a polynomial of degree 3 + 3 + 2 = 8 in t, integrated
// exactly (up to rounding) by 5-point Gauss-Legendre (exact to degree 9).  Eq. 7.27
double volume_integral(const Cubic& p, double t0, double t1) {
    static constexpr std::array<double, 5> kX{0.0, -0.5384693101056831, 0.5384693101056831,
                                              -0.9061798459386640, 0.9061798459386640};
    static constexpr std::array<double, 5> kW{0.5688888888888889, 0.4786286704993665,
                                              0.4786286704993665, 0.2369268850561891,
                                              0.2369268850561891};
    const double half = 0.5 * (t1 - t0);
    const double mid = 0.5 * (t1 + t0);
    double sum = 0.0;
    for (std::size_t k = 0; k < kX.size(); ++k) {
        const double t = mid + half * kX[k];
        const V2 q = bez(p, t);
        sum += kW[k] * q.y() * q.x() * bez_d(p, t).x();
    }
    return half * sum;
}

// Control points of the part [0, t] of a cubic (de Casteljau).
Cubic split_left(const Cubic& p, double t) {
    const V2 a = p[0] + t * (p[1] - p[0]);
    const V2 b = p[1] + t * (p[2] - p[1]);
    const V2 c = p[2] + t * (p[3] - p[2]);
    const V2 ab = a + t * (b - a);
    const V2 bc = b + t * (c - b);
    return {p[0], a, ab, ab + t * (bc - ab)};
}

// Composite Gauss-Legendre (8 points per panel) of f over [a, b].
template <typename F>
double gauss_legendre(F f, double a, double b, int panels) {
    static constexpr std::array<double, 4> kX{0.1834346424956498, 0.5255324099163290,
                                              0.7966664774136267, 0.9602898564975363};
    static constexpr std::array<double, 4> kW{0.3626837833783620, 0.3137066458778873,
                                              0.2223810344533745, 0.1012285362903763};
    const double h = (b - a) / panels;
    double sum = 0.0;
    for (int i = 0; i < panels; ++i) {
        const double mid = a + (i + 0.5) * h;
        double s = 0.0;
        for (std::size_t k = 0; k < kX.size(); ++k) {
            s += kW[k] * (f(mid - 0.5 * h * kX[k]) + f(mid + 0.5 * h * kX[k]));
        }
        sum += 0.5 * h * s;
    }
    return sum;
}

// Bisection of a monotone g on [lo, hi] with g(lo) < 0 < g(hi), to the last bit.
template <typename G>
double bisect(G g, double lo, double hi) {
    for (int it = 0; it < 2000; ++it) {
        const double mid = 0.5 * (lo + hi);
        if (mid <= lo || mid >= hi) break;
        if (g(mid) < 0.0) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    return 0.5 * (lo + hi);
}

// ---- disks (Eq. 7.16-7.18) ----------------------------------------------------------------

DiskTruth disk(const std::vector<Eigen::Vector3d>& pts) {
    const auto n = pts.size();
    Eigen::Vector3d c = Eigen::Vector3d::Zero();
    for (const auto& q : pts) c += q;
    c /= static_cast<double>(n);
    Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
    for (const auto& q : pts) cov += (q - c) * (q - c).transpose();
    cov /= static_cast<double>(n);  // Eq. 7.16 (1/n)
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(cov);
    const Eigen::Vector3d ev = es.eigenvalues();  // ascending
    Eigen::Vector3d normal = es.eigenvectors().col(0);
    if (normal.z() < 0.0) normal = -normal;
    normal += Eigen::Vector3d::Zero();  // -0.0 -> 0.0 in the output
    DiskTruth d;
    d.eigenvalues_mm2 = {ev(2), ev(1), ev(0)};
    d.semi_axes_mm = {std::sqrt(2.0 * std::max(0.0, ev(2))),
                      std::sqrt(2.0 * std::max(0.0, ev(1)))};
    d.normal = {normal.x(), normal.y(), normal.z()};
    // Shoelace area of the xy projection, points in angular order (Eq. 7.17).
    double a2 = 0.0;
    for (std::size_t i = 0; i < n; ++i) {
        const auto& p = pts[i];
        const auto& q = pts[(i + 1) % n];
        a2 += p.x() * q.y() - q.x() * p.y();
    }
    d.area_mm2 = std::fabs(0.5 * a2) / std::fabs(normal.z());
    // Mean 3-D distance of opposite points (Eq. 7.18 without the misprinted square).
    double sum = 0.0;
    for (std::size_t i = 0; i < n / 2; ++i) sum += (pts[i] - pts[i + n / 2]).norm();
    d.diameter_mm = sum / static_cast<double>(n / 2);
    return d;
}

// ---- the surface ----------------------------------------------------------------------------

double wall_height_mm(const MaculaPhantomParams& p, const V2& scan_centre, const V2& g) {
    const V2 d = g - scan_centre;
    const double sag = p.wall_radius_mm > 0.0 ? d.squaredNorm() / (2.0 * p.wall_radius_mm) : 0.0;
    return -sag + p.tilt_x * d.x() + p.tilt_y * d.y();
}

struct Vessel {
    V2 point = V2::Zero();   // a point on the centre line (grid mm)
    V2 normal = V2::Zero();  // unit normal of the centre line
    double width_mm = 0.0;
    double raise_mm = 0.0;
};

std::vector<Vessel> make_vessels(const MaculaPhantomParams& p, const V2& centre) {
    std::vector<Vessel> v;
    phantom::Rng rng(p.seed, 0x7E55E1ULL);
    for (int k = 0; k < p.vessels; ++k) {
        Vessel ves;
        const double phi = kPi * rng.uniform();
        ves.normal = V2(std::cos(phi), std::sin(phi));
        // Straight bands 1.0-3.0 mm from the fovea (large vessels spare the foveal pit).
        const double dist = (rng.uniform() < 0.5 ? -1.0 : 1.0) * (1.0 + 2.0 * rng.uniform());
        ves.point = centre + dist * ves.normal;
        ves.width_mm = 0.06 + 0.06 * rng.uniform();
        ves.raise_mm = 0.001 * (3.0 + 5.0 * rng.uniform());
        v.push_back(ves);
    }
    return v;
}

// Weight in [0, 1] of the vessel profile at grid point g (cos^2 across the band).
double vessel_weight(const Vessel& v, const V2& g) {
    const double s = std::fabs((g - v.point).dot(v.normal)) / (0.5 * v.width_mm);
    if (s >= 1.0) return 0.0;
    const double c = std::cos(0.5 * kPi * s);
    return c * c;
}

double wrap_deg(double deg) {
    deg = std::fmod(deg, 360.0);
    if (deg < 0.0) deg += 360.0;
    return deg;
}

}  // namespace

std::string to_string(MaculaFamily f) { return f == MaculaFamily::kBezier ? "bezier" : "scheibe"; }

void MaculaPhantomParams::validate() const {
    artefacts.validate();
    require(eye == io::Laterality::kOD || eye == io::Laterality::kOS, "eye", "must be OD or OS");
    if (!line && !radial) {
        require(num_bscans >= 2 && num_bscans <= 1024, "bscans", "must be in 2..1024");
    }
    require(!(line && radial), "radial", "and line exclude each other");
    require(!vertical || (!line && !radial), "vertical", "applies to volumes only");
    if (radial) {
        require(radial_lines >= 2 && radial_lines <= 360, "radial_lines", "must be in 2..360");
        // Two half-lines of R = 2 mm plus a crossing offset of up to 1 mm must fit, and the
        // profile is defined to 7 mm from the fovea.
        require(std::isfinite(line_length_mm) && line_length_mm >= 4.0 && line_length_mm <= 12.0,
                "line_length_mm", "must be in [4, 12] mm");
    }
    require(size_x >= 16 && size_x <= 4096, "ascans", "must be in 16..4096");
    require(size_z >= 32 && size_z <= 4096, "depth", "must be in 32..4096");
    require(std::isfinite(scale_x_mm) && scale_x_mm >= 0.0, "scale_x_mm", "must be >= 0");
    require(std::isfinite(distance_mm) && distance_mm >= 0.0, "distance_mm", "must be >= 0");
    require(std::isfinite(scale_z_mm) && scale_z_mm > 0.0, "scale_z_mm", "must be > 0");
    require(std::isfinite(fovea_dx_mm) && std::fabs(fovea_dx_mm) <= 1.0, "fovea_dx_mm",
            "must be within +-1 mm");
    require(std::isfinite(fovea_dy_mm) && std::fabs(fovea_dy_mm) <= 1.0, "fovea_dy_mm",
            "must be within +-1 mm");
    require(!line || fovea_dy_mm == 0.0, "fovea_dy_mm", "must be 0 for a line scan");
    require(std::isfinite(grid_hint_dx_mm) && std::isfinite(grid_hint_dy_mm), "grid_hint",
            "must be finite");
    require(std::isfinite(wall_radius_mm) && wall_radius_mm >= 0.0 &&
                (wall_radius_mm == 0.0 || wall_radius_mm >= 10.0),
            "wall_radius_mm", "must be 0 (flat) or >= 10");
    require(std::isfinite(tilt_x) && std::fabs(tilt_x) <= 0.2, "tilt_x", "must be within +-0.2");
    require(std::isfinite(tilt_y) && std::fabs(tilt_y) <= 0.2, "tilt_y", "must be within +-0.2");
    require(std::isfinite(noise_um) && noise_um >= 0.0 && noise_um <= 50.0, "noise_um",
            "must be in 0..50");
    require(std::isfinite(missing_fraction) && missing_fraction >= 0.0 &&
                missing_fraction <= 0.5,
            "missing_fraction", "must be in 0..0.5");
    require(vessels >= 0 && vessels <= 50, "vessels", "must be in 0..50");
    require(std::isfinite(thickness_offset_mm) && std::fabs(thickness_offset_mm) <= 0.1,
            "thickness_offset_mm", "must be within +-0.1 mm");
    require(std::isfinite(pit_depth_scale) && pit_depth_scale >= 0.5 && pit_depth_scale <= 1.5,
            "pit_depth_scale", "must be in [0.5, 1.5]");
    require(std::isfinite(rotation_deg) && std::fabs(rotation_deg) <= 45.0, "rotation_deg",
            "must be within +-45 deg");
    require(std::isfinite(radial_scale) && radial_scale >= 0.7 && radial_scale <= 1.3,
            "radial_scale", "must be in [0.7, 1.3]");
    require(speckle.looks > 0.0 && std::isfinite(speckle.looks), "speckle.looks", "must be > 0");
    for (const double w : {speckle.axial_half_width_px, speckle.lateral_half_width_px}) {
        require(w >= 0.0 && w <= 20.0, "speckle grain", "half-widths must be in 0..20 px");
    }
    if (speckle.axial_half_width_px > 0.0 || speckle.lateral_half_width_px > 0.0) {
        require(speckle.looks <= 64.0 && speckle.looks == std::round(speckle.looks),
                "speckle.looks", "must be a whole number in 1..64 with a speckle grain");
    }
}

void MaculaTruthOptions::validate() const {
    require(num_half_lines >= 4 && num_half_lines % 2 == 0 && num_half_lines <= 3600,
            "num_half_lines", "must be even and in 4..3600");
    require(std::isfinite(radius_mm) && radius_mm > 0.0 && radius_mm <= 5.0, "radius_mm",
            "must be in (0, 5]");
    require(std::isfinite(tau_mm) && tau_mm > 0.0 && tau_mm < 0.05, "tau_mm",
            "must be in (0, 0.05)");
    require(std::isfinite(inner_radius_mm) && inner_radius_mm > 0.0 &&
                inner_radius_mm <= radius_mm,
            "inner_radius_mm", "must be in (0, radius_mm]");
    require(quadrature_panels >= 8 && quadrature_panels <= 1 << 16, "quadrature_panels",
            "must be in 8..65536");
}

std::array<V2, 4> BezierProfile::interior() const {
    return {V2(0.0, cft_mm), V2(alpha_mm, cft_mm), V2(rim_radius_mm - beta_mm, rim_height_mm),
            V2(rim_radius_mm, rim_height_mm)};  // Eq. 7.5
}

std::array<V2, 4> BezierProfile::exterior() const {
    const V2 p0(rim_radius_mm, rim_height_mm);
    return {p0, p0 + V2(alpha_ext_mm, 0.0), ext_p2, ext_p3};  // Eq. 7.6
}

double ScheibeProfile::thickness_mm(double r) const {
    const double u = mu * std::pow(r, gamma);
    const double e = std::exp(-u);
    return cft_mm + sigma2_mm * u * e + a_mm * (1.0 - e);
}

double ScheibeProfile::slope(double r) const {
    if (r <= 0.0) return 0.0;
    const double u = mu * std::pow(r, gamma);
    const double du = mu * gamma * std::pow(r, gamma - 1.0);
    return (sigma2_mm * (1.0 - u) + a_mm) * std::exp(-u) * du;
}

double ScheibeProfile::curvature(double r) const {
    const double u = mu * std::pow(r, gamma);
    const double e = std::exp(-u);
    const double du = mu * gamma * std::pow(r, gamma - 1.0);
    const double ddu = mu * gamma * (gamma - 1.0) * std::pow(r, gamma - 2.0);
    return (sigma2_mm * (u - 2.0) - a_mm) * e * du * du + (sigma2_mm * (1.0 - u) + a_mm) * e * ddu;
}

double ScheibeProfile::rim_radius_mm() const {
    const double u_star = 1.0 + a_mm / sigma2_mm;  // d/du [sigma^2 u e^-u + a(1 - e^-u)] = 0
    return std::pow(u_star / mu, 1.0 / gamma);
}

// Human-like parameters (thesis Table 7.3: CFT 0.224, rim height 0.352, rim diameter 2.13,
// alpha_m 0.25, beta_m 0.61 mm), nasal rim higher and farther than temporal.
BezierProfile bezier_profile(double theta_deg, bool flat) {
    const double t = theta_deg / kDeg;
    const double c1 = std::cos(t);
    const double s1 = std::sin(t);
    const double c2 = std::cos(2 * t);
    BezierProfile b;
    b.cft_mm = flat ? 0.235 : 0.225;
    b.rim_radius_mm = (flat ? 1.25 : 1.10) + 0.08 * c1 + 0.04 * s1 + 0.03 * c2;
    b.rim_height_mm = 0.350 + 0.015 * c1 + 0.008 * s1 - 0.004 * c2;
    if (flat) {
        b.alpha_mm = 0.55 + 0.05 * c1 - 0.02 * s1;
        b.beta_mm = 0.40 + 0.03 * s1 + 0.02 * c2;
    } else {
        b.alpha_mm = 0.26 + 0.04 * c1 - 0.02 * s1;
        b.beta_mm = 0.55 + 0.04 * s1 + 0.02 * c2;
    }
    b.alpha_ext_mm = 0.45 + 0.05 * c1;
    b.ext_p2 = V2(3.2 + 0.2 * c1, b.rim_height_mm - 0.055 + 0.01 * c1);
    b.ext_p3 = V2(kBezierEndRadiusMm, b.rim_height_mm - 0.085 + 0.02 * c1);
    return b;
}

ScheibeProfile scheibe_profile(double theta_deg, bool flat) {
    const double t = theta_deg / kDeg;
    const double c1 = std::cos(t);
    const double s1 = std::sin(t);
    const double c2 = std::cos(2 * t);
    ScheibeProfile s;
    s.cft_mm = flat ? 0.235 : 0.225;
    s.a_mm = 0.07 + 0.012 * c1;
    s.sigma2_mm = 0.22 + 0.015 * c1 + 0.008 * s1;
    s.gamma = (flat ? 3.2 : 2.2) + 0.15 * c2;
    // mu from the wanted rim radius: r* = (u*/mu)^(1/gamma).
    const double r_rim = (flat ? 1.25 : 1.10) + 0.08 * c1 + 0.04 * s1 + 0.03 * c2;
    const double u_star = 1.0 + s.a_mm / s.sigma2_mm;
    s.mu = u_star / std::pow(r_rim, s.gamma);
    return s;
}

BezierProfile bezier_profile(double theta_deg, const MaculaPhantomParams& p) {
    BezierProfile b = bezier_profile(theta_deg - p.rotation_deg, p.flat);
    if (p.radial_scale != 1.0) {
        // x' = k x on every control point but the exterior's end (kept at 7 mm): both curves
        // stay of the CuBe form with horizontal tangents at the rim.
        const double k = p.radial_scale;
        b.rim_radius_mm *= k;
        b.alpha_mm *= k;
        b.beta_mm *= k;
        b.alpha_ext_mm *= k;
        b.ext_p2.x() *= k;
    }
    if (p.thickness_offset_mm == 0.0 && p.pit_depth_scale == 1.0) return b;
    // y' = y + offset + (s - 1)(y - ref) on every control point's height: a Bezier curve is
    // affine-invariant, so the new curve is the old one with its heights mapped.
    const auto map = [&](double y) {
        return y + p.thickness_offset_mm + (p.pit_depth_scale - 1.0) * (y - kShapeReferenceMm);
    };
    b.cft_mm = map(b.cft_mm);
    b.rim_height_mm = map(b.rim_height_mm);
    b.ext_p2.y() = map(b.ext_p2.y());
    b.ext_p3.y() = map(b.ext_p3.y());
    return b;
}

ScheibeProfile scheibe_profile(double theta_deg, const MaculaPhantomParams& p) {
    ScheibeProfile s = scheibe_profile(theta_deg - p.rotation_deg, p.flat);
    s.mu /= std::pow(p.radial_scale, s.gamma);  // f(r / k): u = mu (r / k)^gamma
    if (p.thickness_offset_mm == 0.0 && p.pit_depth_scale == 1.0) return s;
    // f' = s f + (1 - s) ref + offset: CFT' = s CFT + (1 - s) ref + offset, sigma^2' = s sigma^2,
    // a' = s a (u* = 1 + a / sigma^2, hence the rim radius, is unchanged).
    const double k = p.pit_depth_scale;
    s.cft_mm = k * s.cft_mm + (1.0 - k) * kShapeReferenceMm + p.thickness_offset_mm;
    s.sigma2_mm *= k;
    s.a_mm *= k;
    return s;
}

double macula_thickness_mm(const MaculaPhantomParams& p, double r, double theta_deg) {
    if (p.family == MaculaFamily::kScheibe) {
        return scheibe_profile(theta_deg, p).thickness_mm(r);
    }
    const BezierProfile b = bezier_profile(theta_deg, p);
    if (r <= b.rim_radius_mm) {
        const Cubic in = b.interior();
        return bez(in, solve_x(in, r)).y();
    }
    if (r > kBezierEndRadiusMm) {
        throw UsageError("macula phantom: a grid point lies " + std::to_string(r) +
                         " mm from the fovea, beyond the profile's 7 mm: reduce the field or "
                         "the fovea offset");
    }
    const Cubic ex = b.exterior();
    return bez(ex, solve_x(ex, r)).y();
}

phantom::VolumeLayout macula_layout(const MaculaPhantomParams& p) {
    p.validate();
    phantom::VolumeLayout l;
    if (p.radial) {
        // The square field of side L about the crossing: its grid is the truth frame; the
        // lines are placed by make_macula_phantom (radial_line_direction).
        l.pattern = io::ScanPattern::kRadial;
        l.laterality = p.eye;
        l.size_x = p.size_x;
        l.size_z = p.size_z;
        l.num_bscans = p.radial_lines;
        l.scale_x_mm = p.line_length_mm / (p.size_x - 1);
        l.scale_z_mm = p.scale_z_mm;
        l.distance_mm = p.line_length_mm / std::max(1, p.radial_lines - 1);
        l.slo_field_deg = 30;
        l.validate();
        return l;
    }
    l.pattern = p.line ? io::ScanPattern::kLine : io::ScanPattern::kVolume;
    l.vertical = p.vertical;
    l.laterality = p.eye;
    l.size_x = p.size_x;
    l.size_z = p.size_z;
    l.num_bscans = p.line ? 1 : p.num_bscans;
    l.scale_x_mm = p.scale_x_mm > 0.0 ? p.scale_x_mm : kFieldWidthMm / (p.size_x - 1);
    l.scale_z_mm = p.scale_z_mm;
    l.distance_mm = p.line ? 0.0
                           : (p.distance_mm > 0.0 ? p.distance_mm
                                                  : kFieldHeightMm / (p.num_bscans - 1));
    l.slo_field_deg = 30;
    l.validate();
    return l;
}

phantom::AcquisitionShifts macula_acquisition_shifts(const MaculaPhantomParams& p) {
    const phantom::VolumeLayout l = macula_layout(p);
    return phantom::acquisition_shifts(p.artefacts, l.num_bscans, l.scale_z_mm, l.scale_x_mm,
                                       p.radial || p.line, p.seed);
}

Eigen::Vector2d macula_centre_mm(const MaculaPhantomParams& p) {
    const phantom::GridFrame f = phantom::grid_frame(macula_layout(p));
    return f.centre_mm() + V2(p.fovea_dx_mm, p.line ? 0.0 : p.fovea_dy_mm);
}

Eigen::Vector2d radial_line_direction(const MaculaPhantomParams& p, int k) {
    // Grid +x is SLO +x and grid +y superior (phantom_common.h): the angle runs from SLO +x
    // towards superior.
    const double phi = kPi * k / p.radial_lines;
    return {std::cos(phi), std::sin(phi)};
}

std::vector<Eigen::Vector2d> macula_sample_points(const MaculaPhantomParams& p) {
    const phantom::VolumeLayout l = macula_layout(p);
    const auto nx = static_cast<std::size_t>(l.size_x);
    const auto nb = static_cast<std::size_t>(l.num_bscans);
    std::vector<V2> pts;
    pts.reserve(nb * nx);
    const V2 crossing = phantom::grid_frame(l).centre_mm();
    for (std::size_t b = 0; b < nb; ++b) {
        const V2 u = p.radial ? radial_line_direction(p, static_cast<int>(b)) : V2::Zero();
        for (std::size_t a = 0; a < nx; ++a) {
            const double x = static_cast<double>(a) * l.scale_x_mm;
            if (p.radial) {
                pts.push_back(crossing + (x - 0.5 * p.line_length_mm) * u);
            } else {
                pts.emplace_back(x, static_cast<double>(b) * l.distance_mm);
            }
        }
    }
    return pts;
}

namespace {

// One half-line of a Bezier-family eye, in closed form; returns the central foveal thickness.
double bezier_half_line(const MaculaPhantomParams& p, const MaculaTruthOptions& o,
                        HalfLineTruth& h) {
    const double tau = o.tau_mm;
    const BezierProfile b = bezier_profile(h.angle_deg, p);
    const Cubic in = b.interior();
    const Cubic ex = b.exterior();
    h.rim_radius_mm = b.rim_radius_mm;
    h.rim_height_mm = b.rim_height_mm;
    h.alpha_mm = b.alpha_mm;
    h.beta_mm = b.beta_mm;
    // Maximum slope (docs/algorithms/cube.md `max_pit_slope_deg`): dy/dx = 2 dy t(1-t) / (a(1-t)^2
    // + 2(w-a-b)t(1-t) + b t^2) is largest at t_m = sqrt(a)/(sqrt(a)+sqrt(b)) with value
    // dy/(sqrt(ab) + w - a - b).
    const double dy = b.rim_height_mm - b.cft_mm;
    const double sa = std::sqrt(b.alpha_mm);
    const double sb = std::sqrt(b.beta_mm);
    const double tm = sa / (sa + sb);
    const double s =
        dy / (sa * sb + b.rim_radius_mm - b.alpha_mm - b.beta_mm);  // Eq. 7.20 corrected
    h.max_slope_deg = std::atan(s) * kDeg;
    const V2 q = bez(in, tm);
    h.slope_point = {q.x(), q.y()};
    // Pit flat: y(t) = CFT + dy (3t^2 - 2t^3) = CFT + tau (Eq. 7.24-7.25 on Q_I).
    const double tf =
        bisect([&](double x) { return dy * (3 * x * x - 2 * x * x * x) - tau; }, 0.0, 1.0);
    h.pit_flat_radius_mm = bez(in, tf).x();
    h.rim_volume_mm3 = volume_integral(in, 0.0, 1.0);  // Eq. 7.27
    if (o.inner_radius_mm <= b.rim_radius_mm) {
        h.inner_rim_volume_mm3 = volume_integral(in, 0.0, solve_x(in, o.inner_radius_mm));
    } else {  // r_u passes the rim: the exterior counts too (Eq. 7.28)
        h.inner_rim_volume_mm3 = volume_integral(in, 0.0, 1.0) +
                                 volume_integral(ex, 0.0, solve_x(ex, o.inner_radius_mm));
    }
    for (const V2& c : in) h.interior_control_points.push_back({c.x(), c.y()});
    for (const V2& c : ex) h.exterior_control_points.push_back({c.x(), c.y()});
    for (const V2& c : split_left(ex, solve_x(ex, o.radius_mm))) {
        h.exterior_to_r_control_points.push_back({c.x(), c.y()});
    }
    return b.cft_mm;
}

// The quadrature errors of the Scheibe family's volumes, summed over the half-lines.
struct QuadratureErrors {
    double rim_volume = 0.0;
    double inner_rim_volume = 0.0;
};

// One half-line of a Scheibe-family eye, numerically to the last bit (the volumes by
// quadrature, whose errors are added to `errors`); returns the central foveal thickness.
double scheibe_half_line(const MaculaPhantomParams& p, const MaculaTruthOptions& o,
                         HalfLineTruth& h, QuadratureErrors& errors) {
    const double tau = o.tau_mm;
    const ScheibeProfile sp = scheibe_profile(h.angle_deg, p);
    const double cft = sp.cft_mm;
    h.rim_radius_mm = sp.rim_radius_mm();
    h.rim_height_mm = sp.thickness_mm(h.rim_radius_mm);
    // The steepest point is the inflection (T'' = 0) inside the pit: bracket it on a
    // dense grid (exactly one sign change expected), then bisect to the last bit.
    constexpr int kDense = 4000;
    int changes = 0;
    double lo = 0.0;
    double hi = 0.0;
    double prev_r = h.rim_radius_mm / kDense;
    double prev = sp.curvature(prev_r);
    for (int k = 2; k < kDense; ++k) {
        const double r = h.rim_radius_mm * k / kDense;
        const double c = sp.curvature(r);
        if ((prev > 0.0) != (c > 0.0)) {
            ++changes;
            lo = prev_r;
            hi = r;
        }
        prev = c;
        prev_r = r;
    }
    if (changes != 1) {
        // Unreachable from input: the built-in profiles have one, and validate() keeps the
        // variation affine (T'' scaled by pit_depth_scale > 0, r by radial_scale).
        throw InternalError("Scheibe profile without a single inflection in the pit");
    }
    const double rs = bisect([&](double r) { return -sp.curvature(r); }, lo, hi);
    h.max_slope_deg = std::atan(sp.slope(rs)) * kDeg;
    h.slope_point = {rs, sp.thickness_mm(rs)};
    h.pit_flat_radius_mm = bisect(
        [&](double r) { return sp.thickness_mm(r) - cft - tau; }, 0.0, h.rim_radius_mm);
    auto integrand = [&](double r) { return sp.thickness_mm(r) * r; };
    auto quad = [&](double r1, double& err) {
        const double coarse = gauss_legendre(integrand, 0.0, r1, o.quadrature_panels);
        const double fine = gauss_legendre(integrand, 0.0, r1, 2 * o.quadrature_panels);
        err = std::max(err, std::fabs(fine - coarse));
        return fine;
    };
    double e1 = 0.0;
    double e2 = 0.0;
    h.rim_volume_mm3 = quad(h.rim_radius_mm, e1);
    h.inner_rim_volume_mm3 = quad(o.inner_radius_mm, e2);
    errors.rim_volume += e1;
    errors.inner_rim_volume += e2;
    return cft;
}

// The eye's values from its half-lines (Eq. 7.15-7.29) and the disks through their points.
void combine_half_lines(const MaculaPhantomParams& p, bool bez_family,
                        const std::vector<Eigen::Vector3d>& rim_pts,
                        const std::vector<Eigen::Vector3d>& slope_pts,
                        const std::vector<Eigen::Vector3d>& flat_pts, MaculaTruth& t) {
    const double inv_n = 1.0 / static_cast<double>(t.half_lines.size());
    double slope_sum = 0.0;
    double flat_sum = 0.0;
    double vr = 0.0;
    double vir = 0.0;
    double alpha_sum = 0.0;
    double beta_sum = 0.0;
    double rim_sum = 0.0;
    for (const auto& h : t.half_lines) {
        rim_sum += h.rim_height_mm;
        slope_sum += h.max_slope_deg;
        flat_sum += h.pit_flat_radius_mm;
        vr += h.rim_volume_mm3;
        vir += h.inner_rim_volume_mm3;
        alpha_sum += h.alpha_mm.value_or(0.0);
        beta_sum += h.beta_mm.value_or(0.0);
    }
    t.rim_height_mm = rim_sum * inv_n;  // Eq. 7.15
    t.pit_depth_mm = t.rim_height_mm - t.cft_mm;  // Eq. 7.19
    t.max_pit_slope_deg = slope_sum * inv_n;  // Eq. 7.21 on atan(s_i)
    t.pit_flat_diameter_mm = 2.0 * flat_sum * inv_n;  // Eq. 7.26
    if (bez_family) {
        t.alpha_mean_mm = alpha_sum * inv_n;
        t.beta_mean_mm = beta_sum * inv_n;
    }
    if (!p.line) {
        t.rim = disk(rim_pts);
        t.slope = disk(slope_pts);
        t.pit_flat = disk(flat_pts);
        t.rim_volume_mm3 = 2.0 * kPi * inv_n * vr;   // Eq. 7.27
        t.inner_rim_volume_mm3 = 2.0 * kPi * inv_n * vir;  // Eq. 7.28
        t.pit_volume_mm3 = t.rim.area_mm2 * t.rim_height_mm - t.rim_volume_mm3;  // Eq. 7.29
    }
}

// Method and accuracy of each value. Rounding of a closed form in double: ~1e-15 mm.
void add_truth_accuracy(const MaculaPhantomParams& p, const MaculaTruthOptions& o,
                        bool bez_family, const QuadratureErrors& quad_err, MaculaTruth& t) {
    const double inv_n = 1.0 / static_cast<double>(t.half_lines.size());
    const double quad_vr_err = quad_err.rim_volume;
    const double quad_vir_err = quad_err.inner_rim_volume;
    auto add = [&](const std::string& name, const std::string& method, double err) {
        t.accuracy.emplace_back(name, TruthAccuracy{method, err});
    };
    constexpr double kRound = 1e-14;
    add("centre_x_mm", "generator input (scan centre + fovea offset)", 0.0);
    add("centre_y_mm", "generator input (scan centre + fovea offset)", 0.0);
    add("cft_mm", "profile value at r = 0 (closed form)", kRound);
    if (bez_family) {
        add("rim_height_mm", "mean of the interior P3.y (closed form)", kRound);
        add("max_slope_deg",
            "closed form dy/(sqrt(alpha beta) + w - alpha - beta) at "
            "t_m = sqrt(a)/(sqrt(a)+sqrt(b))",
            1e-12);
        add("pit_flat_radius_mm",
            "x(t_f), t_f by bisection to the last bit of 3t^2 - 2t^3 = tau/dy", 1e-14);
        add("rim_volume_mm3",
            "exact polynomial integral of Q_y Q_x dQ_x/dt (5-point Gauss-Legendre, exact to "
            "degree 9)",
            1e-14);
        add("inner_rim_volume_mm3",
            "exact polynomial integral up to t_u (x(t_u) = r_u by safeguarded Newton)", 1e-14);
    } else {
        add("rim_height_mm", "closed form f(r*), u* = 1 + a/sigma^2", kRound);
        add("max_slope_deg",
            "inflection f''(r) = 0 bracketed on 4000 samples and bisected to the last bit", 1e-10);
        add("pit_flat_radius_mm", "bisection of f(r) = CFT + tau to the last bit", 1e-14);
        add("rim_volume_mm3",
            "composite 8-point Gauss-Legendre, " + std::to_string(2 * o.quadrature_panels) +
                " panels; error = change from halving the panel count",
            2.0 * kPi * inv_n * quad_vr_err);
        add("inner_rim_volume_mm3",
            "composite 8-point Gauss-Legendre, " + std::to_string(2 * o.quadrature_panels) +
                " panels; error = change from halving the panel count",
            2.0 * kPi * inv_n * quad_vir_err);
    }
    if (!p.line) {
        add("rim_diameter_mm, slope_diameter_mm, *_disk_*",
            "covariance eigen-decomposition (Eigen::SelfAdjointEigenSolver), shoelace area and "
            "opposite-point distances of the points above",
            1e-12);
        add("pit_volume_mm3", "A_3D(rim) * h_r - V_r from the values above",
            t.rim.area_mm2 * 1e-12 +
                (bez_family ? 1e-14 : 2.0 * kPi * inv_n * quad_vr_err));
    }
}

}  // namespace

MaculaTruth macula_truth(const MaculaPhantomParams& p, const MaculaTruthOptions& o) {
    p.validate();
    o.validate();
    const phantom::GridFrame frame = phantom::grid_frame(macula_layout(p));
    const V2 centre = macula_centre_mm(p);
    MaculaTruth t;
    t.line_scan = p.line;
    t.centre_x_mm = centre.x();
    t.centre_y_mm = centre.y();
    const bool bez_family = p.family == MaculaFamily::kBezier;
    // A line scan has the two half-lines left and right of the centre (docs/algorithms/cube.md
    // "Parameters", line scans); a radial scan two per line.
    const int n = p.line ? 2 : p.radial ? 2 * p.radial_lines : o.num_half_lines;
    const double tau = o.tau_mm;
    QuadratureErrors quad_err;
    std::vector<Eigen::Vector3d> rim_pts;
    std::vector<Eigen::Vector3d> slope_pts;
    std::vector<Eigen::Vector3d> flat_pts;
    for (int i = 0; i < n; ++i) {
        HalfLineTruth h;
        h.angle_deg = 360.0 * i / n;
        const double cft =
            bez_family ? bezier_half_line(p, o, h) : scheibe_half_line(p, o, h, quad_err);
        t.cft_mm = cft;
        const V2 g = frame.grid_direction(h.angle_deg);
        auto point = [&](double r, double z) {
            return Eigen::Vector3d(centre.x() + r * g.x(), centre.y() + r * g.y(), z);
        };
        rim_pts.push_back(point(h.rim_radius_mm, h.rim_height_mm));
        slope_pts.push_back(point(h.slope_point[0], h.slope_point[1]));
        flat_pts.push_back(point(h.pit_flat_radius_mm, cft + tau));
        t.half_lines.push_back(std::move(h));
    }
    combine_half_lines(p, bez_family, rim_pts, slope_pts, flat_pts, t);
    add_truth_accuracy(p, o, bez_family, quad_err, t);
    return t;
}

namespace {

// Sectors C0, N1, N2, S1, S2, T1, T2, I1, I2 of an ETDRS grid (1, 3, 6 mm) centred at `c`:
// mean thickness of the generating surface (a device-like hint, not a truth value).
io::ThicknessGrid etdrs_grid(const MaculaPhantomParams& p,
                             const phantom::GridFrame& frame,
                             const V2& fovea,
                             const V2& c) {
    io::ThicknessGrid g;
    g.type = 3;
    g.diameters_mm = {1.0, 3.0, 6.0};
    const V2 slo = frame.to_slo(c);
    g.centre_x_slo_mm = slo.x();
    g.centre_y_slo_mm = slo.y();
    std::array<double, 9> sum{};
    std::array<double, 9> weight{};
    double cmin = 1e9;
    double cmax = -1e9;
    constexpr int kRadial = 60;
    constexpr int kAngular = 72;
    for (int i = 0; i < kRadial; ++i) {
        const double r = 3.0 * (i + 0.5) / kRadial;
        for (int j = 0; j < kAngular; ++j) {
            const double anat = 360.0 * (j + 0.5) / kAngular;
            const V2 q = c + r * frame.grid_direction(anat);
            const V2 d = q - fovea;
            const double th = macula_thickness_mm(p, d.norm(),
                                                  frame.anatomical_angle_deg(d.x(), d.y()));
            std::size_t sector = 0;
            if (r >= 0.5) {
                // N: [-45, 45), S: [45, 135), T: [135, 225), I: [225, 315).
                const int quadrant = static_cast<int>(wrap_deg(anat + 45.0) / 90.0) % 4;
                sector = 1 + 2 * static_cast<std::size_t>(quadrant) + (r >= 1.5 ? 1 : 0);
            } else {
                cmin = std::min(cmin, th);
                cmax = std::max(cmax, th);
            }
            sum[sector] += th * r;
            weight[sector] += r;
        }
    }
    const std::array<double, 9> area{kPi * 0.25,       kPi * 2.0 / 4.0, kPi * 6.75 / 4.0,
                                      kPi * 2.0 / 4.0, kPi * 6.75 / 4.0, kPi * 2.0 / 4.0,
                                      kPi * 6.75 / 4.0, kPi * 2.0 / 4.0, kPi * 6.75 / 4.0};
    double total = 0.0;
    for (std::size_t s = 0; s < 9; ++s) {
        const double mean = sum[s] / weight[s];
        g.cells.push_back({static_cast<float>(mean), static_cast<float>(mean * area[s])});
        total += mean * area[s];
    }
    g.central_thickness_mm = g.cells[0].thickness_mm;
    g.min_central_thickness_mm = static_cast<float>(cmin);
    g.max_central_thickness_mm = static_cast<float>(cmax);
    g.total_volume_mm3 = static_cast<float>(total);
    return g;
}

}  // namespace

namespace {

// True heights (mm) of ILM (with vessels) and BM at every A-scan, the vessel weight (for the
// shadow), and the highest ILM and lowest BM.
struct TrueSurfaces {
    std::vector<double> z_ilm;
    std::vector<double> z_bm;
    std::vector<double> shadow;
    double top = -1e9;
    double bottom = 1e9;
};

TrueSurfaces true_surfaces(const MaculaPhantomParams& p, const MaculaPhantom& out,
                           const std::vector<V2>& points, const std::vector<Vessel>& vessels,
                           std::size_t nb, std::size_t nx) {
    TrueSurfaces s;
    s.z_ilm.resize(nb * nx);
    s.z_bm.resize(nb * nx);
    s.shadow.assign(nb * nx, 0.0);
    const V2 scan_centre = out.frame.centre_mm();
    for (std::size_t b = 0; b < nb; ++b) {
        for (std::size_t a = 0; a < nx; ++a) {
            const V2& g = points[b * nx + a];
            const V2 d = g - out.centre_mm;
            const double th =
                macula_thickness_mm(p, d.norm(), out.frame.anatomical_angle_deg(d.x(), d.y()));
            double raise = 0.0;
            double w_max = 0.0;
            for (const Vessel& v : vessels) {
                const double w = vessel_weight(v, g);
                raise += w * v.raise_mm;
                w_max = std::max(w_max, w);
            }
            const std::size_t i = b * nx + a;
            s.z_bm[i] = wall_height_mm(p, scan_centre, g);
            s.z_ilm[i] = s.z_bm[i] + th + raise;
            s.shadow[i] = w_max;
            s.top = std::max(s.top, s.z_ilm[i]);
            s.bottom = std::min(s.bottom, s.z_bm[i]);
        }
    }
    return s;
}

// Missing A-scans: half the requested fraction as blocks at the B-scan edges (as devices
// lose the segmentation there), the rest at random positions; exactly round(f * N) in all.
std::vector<char> missing_ascans(const MaculaPhantomParams& p, std::size_t nb, std::size_t nx) {
    std::vector<char> missing(nb * nx, 0);
    if (p.missing_fraction <= 0.0) return missing;
    phantom::Rng rng(p.seed, 0x3155ULL);
    const double all = static_cast<double>(nb * nx);
    const auto target = static_cast<std::size_t>(std::llround(p.missing_fraction * all));
    std::size_t count = 0;
    const double edge_mean = 0.25 * p.missing_fraction * static_cast<double>(nx);
    for (std::size_t b = 0; b < nb && count < target; ++b) {
        const auto left = static_cast<std::size_t>(2.0 * edge_mean * rng.uniform());
        const auto right = static_cast<std::size_t>(2.0 * edge_mean * rng.uniform());
        for (std::size_t a = 0; a < left && count < target; ++a) {
            if (!missing[b * nx + a]) {
                missing[b * nx + a] = 1;
                ++count;
            }
        }
        for (std::size_t a = 0; a < right && count < target; ++a) {
            const std::size_t i = b * nx + (nx - 1 - a);
            if (!missing[i]) {
                missing[i] = 1;
                ++count;
            }
        }
    }
    std::vector<std::size_t> free;
    for (std::size_t i = 0; i < missing.size(); ++i) {
        if (!missing[i]) free.push_back(i);
    }
    // Partial Fisher-Yates: the first (target - count) of a random permutation of `free`.
    for (std::size_t k = 0; count < target && k < free.size(); ++k, ++count) {
        const std::size_t j =
            k + static_cast<std::size_t>(rng.uniform() * static_cast<double>(free.size() - k));
        std::swap(free[k], free[std::min(j, free.size() - 1)]);
        missing[free[k]] = 1;
    }
    return missing;
}

// Image depth (pixels) of a height z (mm): the band from the highest ILM to the lowest BM takes
// the middle of the image (a little above centre, leaving room for the choroid).
struct DepthMap {
    double z0 = 0.0;
    double scale_z_mm = 1.0;
    double operator()(double z) const { return (z0 - z) / scale_z_mm; }
};

DepthMap depth_map(const MaculaPhantomParams& p, const phantom::VolumeLayout& layout,
                   const TrueSurfaces& s) {
    const double span_px = (s.top - s.bottom) / layout.scale_z_mm;
    const double noise_px = p.noise_um * 1e-3 / layout.scale_z_mm;
    if (span_px + 12.0 * noise_px > 0.8 * layout.size_z) {
        throw UsageError("macula phantom: retina and eye wall span " +
                         std::to_string(static_cast<int>(std::ceil(span_px))) +
                         " pixels, more than 80 % of depth " + std::to_string(layout.size_z) +
                         ": use a larger --depth or --scale-z, --wall-radius-mm 0 or less tilt");
    }
    return {s.top + 0.4 * (layout.size_z - span_px) * layout.scale_z_mm, layout.scale_z_mm};
}

// Segmentation lines. Inner boundaries follow the layer model of the pixels; the noise is on
// ILM and BM only (what the CuBe analysis uses).
void write_segmentation(const MaculaPhantomParams& p, const phantom::VolumeLayout& layout,
                        const TrueSurfaces& s, const std::vector<char>& missing,
                        const DepthMap& depth, io::Scan& scan) {
    const auto nx = static_cast<std::size_t>(layout.size_x);
    const auto nb = static_cast<std::size_t>(layout.num_bscans);
    const double noise_px = p.noise_um * 1e-3 / layout.scale_z_mm;
    const phantom::RetinaLayers layers;
    constexpr std::array<std::pair<int, int>, 8> kInner{{{2, 1}, {3, 2}, {4, 3}, {5, 4}, {6, 5},
                                                         {8, 6}, {14, 7}, {16, 9}}};
    const auto nan = std::numeric_limits<float>::quiet_NaN();
    for (std::size_t b = 0; b < nb; ++b) {
        phantom::Rng noise(p.seed, 0x5E6000ULL + b);
        io::BScan& bs = scan.bscans[b];
        for (std::size_t a = 0; a < nx; ++a) {
            const std::size_t i = b * nx + a;
            // Draw both noise values for every A-scan so that the noise at an A-scan does not
            // depend on which other A-scans are missing.
            const double n_ilm = noise.normal() * noise_px;
            const double n_bm = noise.normal() * noise_px;
            if (missing[i]) {
                for (auto& line : bs.seg) line[a] = nan;
                continue;
            }
            const double d_ilm = depth(s.z_ilm[i]);
            const double d_bm = depth(s.z_bm[i]);
            bs.seg[0][a] = static_cast<float>(d_ilm + n_ilm);
            bs.seg[1][a] = static_cast<float>(d_bm + n_bm);
            const phantom::ColumnBoundaries cb =
                phantom::retina_boundaries(d_ilm, d_bm, layout.scale_z_mm, layers);
            for (const auto& [line, k] : kInner) {
                if (line < layout.num_seg) {
                    bs.seg[static_cast<std::size_t>(line)][a] =
                        static_cast<float>(cb.depth_px[static_cast<std::size_t>(k)]);
                }
            }
        }
    }
}

// Pixels: the true boundaries (with vessels), layered reflectance, a shadow under vessels,
// speckle; and the SLO.
void render_macula_pixels(const MaculaPhantomParams& p, const phantom::VolumeLayout& layout,
                          const TrueSurfaces& s, const DepthMap& depth,
                          const std::vector<Vessel>& vessels, MaculaPhantom& out) {
    io::Scan& scan = out.scan;
    const auto nx = static_cast<std::size_t>(layout.size_x);
    const auto nb = static_cast<std::size_t>(layout.num_bscans);
    const phantom::RetinaLayers layers;
    for (std::size_t b = 0; b < nb; ++b) {
        auto column = [&](int a, std::span<float> col) {
            const std::size_t i = b * nx + static_cast<std::size_t>(a);
            const phantom::ColumnBoundaries cb = phantom::retina_boundaries(
                depth(s.z_ilm[i]), depth(s.z_bm[i]), layout.scale_z_mm, layers);
            phantom::layered_retina_column(cb, layout.scale_z_mm, layers, col);
            if (s.shadow[i] > 0.0) {
                const double start = cb.depth_px[2];  // below the vessel in the GCL
                for (std::size_t z = 0; z < col.size(); ++z) {
                    if (static_cast<double>(z) > start) {
                        col[z] = static_cast<float>(col[z] * (1.0 - 0.6 * s.shadow[i]));
                    }
                }
            }
        };
        phantom::render_bscan(scan.bscans[b], layout.size_x, layout.size_z, column, p.speckle,
                              p.seed, b);
    }
    // SLO: fundus grey with vignetting, a darker fovea, the optic disc 4.3 mm nasal, and
    // the vessels as dark bands.
    const V2 disc = out.centre_mm + 4.3 * out.frame.grid_direction(0.0) +
                    0.3 * out.frame.grid_direction(90.0);
    const double slo_side = scan.meta.size_x_slo * scan.meta.scale_x_slo_mm;
    const phantom::GridFrame& f = out.frame;
    auto brightness = [&](double xs, double ys) {
        // SLO mm -> grid mm (grid_to_slo is its own inverse here, but use the general form).
        const V2 g = f.grid_to_slo.inverse() * (V2(xs, ys) - f.origin_slo_mm);
        const double rho = (V2(xs, ys) - V2(slo_side / 2, slo_side / 2)).norm() / slo_side;
        double v = 0.45 * (1.0 - 0.6 * rho * rho);
        v *= 1.0 - 0.35 * std::exp(-(g - out.centre_mm).squaredNorm() / (2 * 0.5 * 0.5));
        const double dd = (g - disc).norm();
        v += 0.45 / (1.0 + std::exp((dd - 0.85) / 0.05));
        for (const Vessel& ves : vessels) v *= 1.0 - 0.45 * vessel_weight(ves, g);
        return v;
    };
    phantom::render_slo(scan, brightness, p.seed);
    scan.pixels_loaded = true;
}

// Three acquisition vessels (straight, 1-3 mm from the fovea, 60-150 um wide) and faults
// farther than 2.5 mm from the fovea (outside the CuBe fit's 2 mm).
void apply_macula_artefacts(const MaculaPhantomParams& p, const std::vector<V2>& points,
                            MaculaPhantom& out) {
    std::vector<phantom::VesselPath> paths;
    phantom::Rng rng(p.seed, 0x5AD0ULL);
    for (int k = 0; k < 3; ++k) {
        const double phi = kPi * rng.uniform();
        const V2 normal(std::cos(phi), std::sin(phi));
        const V2 along(-normal.y(), normal.x());
        const double dist = (k % 2 == 0 ? -1.0 : 1.0) * (1.0 + 2.0 * rng.uniform());
        const V2 base = out.centre_mm + dist * normal;
        paths.push_back({{base - 12.0 * along, base + 12.0 * along}, 0.06 + 0.09 * rng.uniform()});
    }
    phantom::apply_acquisition_artefacts(out.scan, points, paths, p.artefacts, 0, 1,
                                         out.centre_mm, 2.5);
}

// The radial lines on the SLO through the crossing; a radial scan has no B-scan Distance.
void place_radial_lines(const MaculaPhantomParams& p, MaculaPhantom& out) {
    io::Scan& scan = out.scan;
    const V2 crossing = out.frame.centre_mm();
    for (std::size_t b = 0; b < scan.bscans.size(); ++b) {
        const V2 u = radial_line_direction(p, static_cast<int>(b));
        const V2 start = out.frame.to_slo(crossing - 0.5 * p.line_length_mm * u);
        const V2 end = out.frame.to_slo(crossing + 0.5 * p.line_length_mm * u);
        scan.bscans[b].start_x_mm = start.x();
        scan.bscans[b].start_y_mm = start.y();
        scan.bscans[b].end_x_mm = end.x();
        scan.bscans[b].end_y_mm = end.y();
    }
    scan.meta.distance_mm = 0.0;
}

}  // namespace

MaculaPhantom make_macula_phantom(const MaculaPhantomParams& p, const MaculaTruthOptions& o) {
    p.validate();
    o.validate();
    const phantom::VolumeLayout layout = macula_layout(p);
    MaculaPhantom out;
    out.frame = phantom::grid_frame(layout);
    out.centre_mm = macula_centre_mm(p);
    out.scan = phantom::make_scan_frame(layout);
    const auto nx = static_cast<std::size_t>(layout.size_x);
    const auto nb = static_cast<std::size_t>(layout.num_bscans);
    const std::vector<Vessel> vessels = make_vessels(p, out.centre_mm);
    // Every A-scan's grid position: the same continuous eye for volumes, lines and radial scans.
    const std::vector<V2> points = macula_sample_points(p);
    TrueSurfaces surfaces = true_surfaces(p, out, points, vessels, nb, nx);
    // The still eye places the retina in the image; a moving one is then sampled where it moved
    // (phantom::acquired_points, every height axial_px[b] pixels deeper) before any line or
    // pixel is drawn.
    const DepthMap depth = depth_map(p, layout, surfaces);
    const phantom::AcquisitionShifts shifts = macula_acquisition_shifts(p);
    const std::vector<V2> moved = phantom::acquired_points(points, layout.size_x, shifts);
    if (moved != points) surfaces = true_surfaces(p, out, moved, vessels, nb, nx);
    for (std::size_t b = 0; b < nb && b < shifts.axial_px.size(); ++b) {
        const double dz_mm = shifts.axial_px[b] * layout.scale_z_mm;
        if (dz_mm == 0.0) continue;
        for (std::size_t i = b * nx; i < (b + 1) * nx; ++i) {
            surfaces.z_ilm[i] -= dz_mm;
            surfaces.z_bm[i] -= dz_mm;
        }
    }
    write_segmentation(p, layout, surfaces, missing_ascans(p, nb, nx), depth, out.scan);
    if (p.pixels) render_macula_pixels(p, layout, surfaces, depth, vessels, out);
    if (p.artefacts.any()) apply_macula_artefacts(p, moved, out);
    if (p.radial) place_radial_lines(p, out);
    if (!p.line && !p.radial) {  // line and radial scans carry no thickness grid
        const V2 hint = out.centre_mm + V2(p.grid_hint_dx_mm, p.grid_hint_dy_mm);
        out.scan.grids.push_back(etdrs_grid(p, out.frame, out.centre_mm, hint));
        out.scan.meta.grid_type = 3;
    }
    out.truth = macula_truth(p, o);
    return out;
}

namespace {

// The acquisition artefacts and the true per-B-scan shifts.
nlohmann::ordered_json acquisition_json(const MaculaPhantomParams& p) {
    const phantom::VolumeLayout l = macula_layout(p);
    const phantom::AcquisitionShifts sh = macula_acquisition_shifts(p);
    std::vector<double> axial_um(sh.axial_px.size());
    std::vector<double> lateral_um(sh.lateral_px.size());
    for (std::size_t b = 0; b < sh.axial_px.size(); ++b) {
        axial_um[b] = sh.axial_px[b] * l.scale_z_mm * 1000.0;
        lateral_um[b] = sh.lateral_px[b] * l.scale_x_mm * 1000.0;
    }
    nlohmann::ordered_json acq;
    acq["motion_sd_um"] = p.artefacts.motion_sd_um;
    acq["lateral_jitter_um"] = p.artefacts.lateral_jitter_um;
    acq["vessel_shadows"] = p.artefacts.vessel_shadows;
    acq["cleft"] = p.artefacts.cleft;
    acq["segmentation_faults"] = p.artefacts.segmentation_faults;
    acq["axial_shift_um"] = axial_um;
    acq["lateral_shift_um"] = lateral_um;
    return acq;
}

}  // namespace

nlohmann::ordered_json macula_truth_json(const MaculaTruth& t,
                                         const MaculaPhantomParams& p,
                                         const MaculaTruthOptions& o) {
    using J = nlohmann::ordered_json;
    const phantom::VolumeLayout l = macula_layout(p);
    J j;
    j["kind"] = "octshape macula phantom truth";
    // The version only (docs/outputs.md, "Provenance"): the documented command reproduces the
    // file bit for bit from any revision of it.
    j["provenance"] = {{"version", kVersion}};
    j["frame"] =
        "grid mm: x along a B-scan (A-scan index * ScaleX), y across B-scans (B-scan index * "
        "Distance), heights are thickness (ILM - BM) in mm; angles anatomical (0 deg nasal, "
        "90 deg superior) for both eyes; disk normals in the grid frame with z >= 0";
    J g;
    g["family"] = to_string(p.family);
    g["flat"] = p.flat;
    g["eye"] = p.eye == io::Laterality::kOS ? "OS" : "OD";
    g["pattern"] = p.line ? "line" : p.radial ? "radial" : "volume";
    if (p.radial) {
        // The lines' crossing in the truth's grid frame (the field's centre).
        const std::array<double, 2> crossing{0.5 * p.line_length_mm, 0.5 * p.line_length_mm};
        const std::array<double, 3> radial{static_cast<double>(p.radial_lines), p.line_length_mm,
                                           std::hypot(p.fovea_dx_mm, p.fovea_dy_mm)};
        g["radial_lines"] = p.radial_lines;
        g["line_length_mm"] = radial[1];
        g["crossing_mm"] = crossing;
        g["crossing_offset_mm"] = radial[2];
    }
    g["bscans"] = l.num_bscans;
    g["ascans"] = l.size_x;
    g["depth"] = l.size_z;
    g["scale_x_mm"] = l.scale_x_mm;
    g["distance_mm"] = l.num_bscans > 1 ? l.distance_mm : 0.0;
    g["scale_z_mm"] = l.scale_z_mm;
    g["fovea_dx_mm"] = p.fovea_dx_mm;
    g["fovea_dy_mm"] = p.fovea_dy_mm;
    g["grid_hint_dx_mm"] = p.grid_hint_dx_mm;
    g["grid_hint_dy_mm"] = p.grid_hint_dy_mm;
    g["wall_radius_mm"] = p.wall_radius_mm;
    g["tilt_x"] = p.tilt_x;
    g["tilt_y"] = p.tilt_y;
    g["noise_um"] = p.noise_um;
    g["missing_fraction"] = p.missing_fraction;
    g["vessels"] = p.vessels;
    if (p.thickness_offset_mm != 0.0 || p.pit_depth_scale != 1.0) {  // cohort phantoms only
        g["thickness_offset_mm"] = p.thickness_offset_mm;
        g["pit_depth_scale"] = p.pit_depth_scale;
    }
    if (p.rotation_deg != 0.0 || p.radial_scale != 1.0) {  // re-scan studies only
        g["rotation_deg"] = p.rotation_deg;
        g["radial_scale"] = p.radial_scale;
    }
    if (p.artefacts.any()) {  // only then (a still phantom's truth file is unchanged)
        j["acquisition"] = acquisition_json(p);
    }
    g["pixels"] = p.pixels;
    g["speckle_looks"] = p.speckle.looks;
    if (p.speckle.axial_half_width_px > 0.0 || p.speckle.lateral_half_width_px > 0.0) {
        // only then (a phantom without a grain keeps its truth file)
        g["speckle_axial_half_width_px"] = p.speckle.axial_half_width_px;
        g["speckle_lateral_half_width_px"] = p.speckle.lateral_half_width_px;
    }
    g["seed"] = p.seed;
    j["generator"] = g;
    J a;
    a["num_half_lines"] = t.line_scan ? 2 : p.radial ? 2 * p.radial_lines : o.num_half_lines;
    a["radius_mm"] = o.radius_mm;
    a["tau_mm"] = o.tau_mm;
    a["inner_radius_mm"] = o.inner_radius_mm;
    j["analysis_options"] = a;
    if (t.line_scan) {
        j["note"] = "line scan: 2-D parameters only (docs/algorithms/cube.md); the 3-D ones are omitted";
    }
    J v;
    v["centre_x_mm"] = t.centre_x_mm;
    v["centre_y_mm"] = t.centre_y_mm;
    v["cft_mm"] = t.cft_mm;
    v["rim_height_mm"] = t.rim_height_mm;
    v["pit_depth_mm"] = t.pit_depth_mm;
    v["max_pit_slope_deg"] = t.max_pit_slope_deg;
    auto put_disk = [&](const std::string& diameter, const std::string& prefix,
                        const DiskTruth& d) {
        v[diameter] = d.diameter_mm;
        v[prefix + "_area_mm2"] = d.area_mm2;
        v[prefix + "_eigenvalues_mm2"] = d.eigenvalues_mm2;
        // Element by element (GCC's -Wnull-dereference misfires on std::array conversion).
        v[prefix + "_semi_axes_mm"] = J::array({d.semi_axes_mm[0], d.semi_axes_mm[1]});
        v[prefix + "_normal"] = d.normal;
    };
    if (!t.line_scan) {
        put_disk("rim_diameter_mm", "rim_disk", t.rim);
        put_disk("slope_diameter_mm", "slope_disk", t.slope);
    }
    v["pit_flat_diameter_mm"] = t.pit_flat_diameter_mm;
    if (!t.line_scan) {
        v["pit_flat_disk_area_mm2"] = t.pit_flat.area_mm2;
        v["pit_flat_disk_eigenvalues_mm2"] = t.pit_flat.eigenvalues_mm2;
        v["pit_flat_disk_semi_axes_mm"] = t.pit_flat.semi_axes_mm;
        v["pit_flat_disk_normal"] = t.pit_flat.normal;
        v["rim_volume_mm3"] = t.rim_volume_mm3;
        v["inner_rim_volume_mm3"] = t.inner_rim_volume_mm3;
        v["pit_volume_mm3"] = t.pit_volume_mm3;
    }
    if (t.alpha_mean_mm) v["alpha_mean_mm"] = *t.alpha_mean_mm;
    if (t.beta_mean_mm) v["beta_mean_mm"] = *t.beta_mean_mm;
    j["parameters"] = v;
    J hl = J::array();
    for (const auto& h : t.half_lines) {
        J e;
        e["angle_deg"] = h.angle_deg;
        e["rim_radius_mm"] = h.rim_radius_mm;
        e["rim_height_mm"] = h.rim_height_mm;
        e["max_slope_deg"] = h.max_slope_deg;
        e["slope_point"] = h.slope_point;
        e["pit_flat_radius_mm"] = h.pit_flat_radius_mm;
        if (h.alpha_mm) e["alpha_mm"] = *h.alpha_mm;
        if (h.beta_mm) e["beta_mm"] = *h.beta_mm;
        if (!h.interior_control_points.empty()) {
            // Element by element: GCC's -Wnull-dereference misfires on nlohmann's conversion of
            // nested std containers.
            auto points = [](const std::vector<std::array<double, 2>>& pts) {
                J arr = J::array();
                for (const auto& q : pts) arr.push_back(J::array({q[0], q[1]}));
                return arr;
            };
            e["interior_control_points"] = points(h.interior_control_points);
            e["exterior_control_points"] = points(h.exterior_control_points);
            e["exterior_to_r_control_points"] = points(h.exterior_to_r_control_points);
        }
        hl.push_back(e);
    }
    j["half_lines"] = hl;
    J acc;
    for (const auto& [name, ta] : t.accuracy) {
        acc[name] = J{{"method", ta.method}, {"abs_error", ta.abs_error}};
    }
    j["accuracy"] = acc;
    return j;
}

}  // namespace octshape::retina
