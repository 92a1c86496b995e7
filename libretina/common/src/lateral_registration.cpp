// Lateral registration of a volume's B-scans (docs/algorithms/onh.md, "Lateral registration").

#include "octshape/retina/lateral_registration.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <string>
#include <utility>

#include <Eigen/Dense>

#include "octshape/error.h"
#include "octshape/retina/radial_geometry.h"
#include "octshape/retina/report_util.h"

namespace octshape::retina {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
// Most B-scans estimated: 2N unknowns, a dense solve per pass (512: ~1 s in all).
constexpr int kMaxBscans = 512;

// A device line at a fractional A-scan (linear between two valid values; NaN outside the
// B-scan or next to a missing value).
inline double line_at(const std::vector<float>& line, double x) {
    const auto n = static_cast<int>(line.size());
    if (!(x >= 0.0) || x > n - 1) return kNaN;
    // x >= 0: the truncation is the floor (and cheaper than the library's).
    const int a0 = std::min(static_cast<int>(x), n - 1);
    const int a1 = std::min(a0 + 1, n - 1);
    const float v0 = line[static_cast<std::size_t>(a0)];
    const float v1 = line[static_cast<std::size_t>(a1)];
    if (!io::is_valid(v0) || !io::is_valid(v1)) return kNaN;
    const double f = x - a0;
    return (1.0 - f) * v0 + f * v1;
}

// A line that bends by more than this (second difference over +-1 A-scan, px) is not linear
// over the one A-scan the Gauss-Newton step trusts: the step of a device fault (an ILM spike of
// whole A-scans). Tukey's weights do not catch it: next to the step the residual can be small
// while the slope, the Jacobian, is the step's height, and one such value outweighs a B-scan's
// smooth ones (a 25 px spike of 4 A-scans pulled five B-scans of the 97 x 256 jittered phantom
// by 20 um: identifiable error 8.9 um instead of 2.4). 8 px is 3.3 SD of the second difference
// of a line with 1 px of independent noise (sqrt(6) px); no value of a fault-free phantom
// bends by 2 px (the fault-free estimate is the same to the bit down to 2 px).
constexpr double kMaxBendPx = 8.0;

// Value and slope (central difference over +-1 A-scan) of a line at x; false if missing or
// bent beyond kMaxBendPx.
inline bool sample(const std::vector<float>& line, double x, double& v, double& g) {
    v = line_at(line, x);
    const double lo = line_at(line, x - 1.0);
    const double hi = line_at(line, x + 1.0);
    if (!std::isfinite(v) || !std::isfinite(lo) || !std::isfinite(hi)) return false;
    if (std::fabs(lo + hi - 2.0 * v) > kMaxBendPx) return false;
    g = 0.5 * (hi - lo);
    return true;
}

// The lines the model uses: ILM and BM where the scan has them.
std::vector<int> model_lines(const io::Scan& scan) {
    std::vector<int> out;
    const auto nx = static_cast<std::size_t>(scan.meta.size_x);
    for (int k : {static_cast<int>(io::Layer::kILM), static_cast<int>(io::Layer::kBM)}) {
        bool any = false;
        for (const io::BScan& b : scan.bscans) {
            any = any || (static_cast<int>(b.seg.size()) > k && b.seg[static_cast<std::size_t>(k)].size() == nx);
        }
        if (any) out.push_back(k);
    }
    return out;
}

const std::vector<float>* line_of(const io::Scan& scan, int b, int k) {
    const io::BScan& bs = scan.bscans[static_cast<std::size_t>(b)];
    if (static_cast<int>(bs.seg.size()) <= k) return nullptr;
    const auto& l = bs.seg[static_cast<std::size_t>(k)];
    return l.size() == static_cast<std::size_t>(scan.meta.size_x) ? &l : nullptr;
}

// One Gauss-Newton pass: the second differences across B-scans of the registered lines at the
// current shifts s and offsets o (px), their Jacobian accumulated into the normal equations
// (unknowns: s then o) with weights from `scale` (Tukey; scale <= 0: unweighted). Returns the
// absolute residuals (for the next scale); counts inliers / outliers.
struct Pass {
    Eigen::MatrixXd N;
    Eigen::VectorXd rhs;
    std::vector<double> abs_res;
    double ss = 0.0;       // weighted-in residuals, squared (inliers)
    double inliers = 0.0;
    int rejected = 0;
};

// Value, slope and validity (sample()) of every used B-scan's model lines at the current shifts,
// once per pass: each B-scan's samples serve up to three second differences. Indexed
// [(b * lines + line) * nx + a]; a B-scan not used or a line it lacks: not valid.
struct Samples {
    std::vector<double> v, g;
    std::vector<char> ok;
};

// (`out`'s buffers are reused from pass to pass.)
void sample_lines(const io::Scan& scan, const std::vector<int>& lines,
                  const std::vector<char>& use, const Eigen::VectorXd& s, Samples& out) {
    const int nb = scan.num_bscans();
    const int nx = scan.meta.size_x;
    const auto nl = lines.size();
    const std::size_t n = static_cast<std::size_t>(nb) * nl * static_cast<std::size_t>(nx);
    out.v.resize(n);
    out.g.resize(n);
    out.ok.assign(n, 0);
    for (int b = 0; b < nb; ++b) {
        if (!use[static_cast<std::size_t>(b)]) continue;
        for (std::size_t li = 0; li < nl; ++li) {
            const std::vector<float>* L = line_of(scan, b, lines[li]);
            if (!L) continue;
            const std::size_t base = (static_cast<std::size_t>(b) * nl + li) * static_cast<std::size_t>(nx);
            for (int a = 0; a < nx; ++a) {
                const std::size_t i = base + static_cast<std::size_t>(a);
                out.ok[i] = sample(*L, a + s(b), out.v[i], out.g[i]) ? 1 : 0;
            }
        }
    }
}

// The order of the differences across B-scans (second: a smooth surface's curvature).
constexpr int kOrder = 2;

Pass gauss_newton_pass(const io::Scan& scan, const std::vector<int>& lines,
                       const std::vector<char>& use, const Eigen::VectorXd& s,
                       const Eigen::VectorXd& o, double scale, Samples& smp) {
    const int nb = scan.num_bscans();
    const int nx = scan.meta.size_x;
    constexpr int m = kOrder;
    constexpr std::size_t m1 = m + 1;
    constexpr std::size_t nj = 2 * m1;
    const auto nl = lines.size();
    Pass p;
    p.N = Eigen::MatrixXd::Zero(2 * nb, 2 * nb);
    p.rhs = Eigen::VectorXd::Zero(2 * nb);
    p.abs_res.reserve(static_cast<std::size_t>(nb) * nl * static_cast<std::size_t>(nx));
    sample_lines(scan, lines, use, s, smp);
    // The coefficients of the second difference, (-1)^(m-j) binom(m, j), as constants: the
    // products with them fold.
    constexpr std::array<double, m1> c{1.0, -2.0, 1.0};
    std::array<std::size_t, m1> base{};
    std::array<double, m1> v{};
    std::array<double, m1> g{};
    std::array<double, m1> off{};
    std::array<int, nj> idx{};
    std::array<double, nj> jac{};
    // d r / d o_{b0+j} = -c_j: constant.
    for (std::size_t j = 0; j < m1; ++j) jac[j + m1] = -c[j];
    // The triple's block of the normal equations, accumulated locally: every entry receives the
    // same additions in the same order as in N itself (loaded before, stored after), so the
    // result is N's to the bit.
    std::array<double, nj * nj> Nl{};
    std::array<double, nj> rl{};
    for (int b0 = 0; b0 + m < nb; ++b0) {
        bool all = true;
        for (int j = 0; j <= m; ++j) all = all && use[static_cast<std::size_t>(b0 + j)];
        if (!all) continue;
        for (std::size_t j = 0; j < m1; ++j) {
            idx[j] = b0 + static_cast<int>(j);
            idx[j + m1] = nb + b0 + static_cast<int>(j);
            off[j] = o(b0 + static_cast<int>(j));
        }
        for (std::size_t i = 0; i < nj; ++i) {
            rl[i] = p.rhs(idx[i]);
            for (std::size_t j = 0; j < nj; ++j) Nl[i * nj + j] = p.N(idx[i], idx[j]);
        }
        for (std::size_t li = 0; li < nl; ++li) {
            bool have = true;
            for (int j = 0; j <= m; ++j) have = have && line_of(scan, b0 + j, lines[li]) != nullptr;
            if (!have) continue;
            for (std::size_t j = 0; j < m1; ++j) {
                base[j] = ((static_cast<std::size_t>(b0) + j) * nl + li) * static_cast<std::size_t>(nx);
            }
            for (int a = 0; a < nx; ++a) {
                bool ok = true;
                for (std::size_t j = 0; j < m1; ++j) {
                    const std::size_t i = base[j] + static_cast<std::size_t>(a);
                    ok = ok && smp.ok[i] != 0;
                    v[j] = smp.v[i];
                    g[j] = smp.g[i];
                }
                if (!ok) continue;
                double r = 0.0;
                for (std::size_t j = 0; j < m1; ++j) r += c[j] * (v[j] - off[j]);
                p.abs_res.push_back(std::fabs(r));
                double w = 1.0;
                if (scale > 0.0) {
                    const double u = r / scale;
                    w = std::fabs(u) < 1.0 ? (1.0 - u * u) * (1.0 - u * u) : 0.0;
                }
                if (w <= 0.0) {
                    ++p.rejected;
                    continue;
                }
                p.ss += r * r;
                p.inliers += 1.0;
                // d r / d s_{b0+j} = c_j g_j.
                for (std::size_t j = 0; j < m1; ++j) jac[j] = c[j] * g[j];
                for (std::size_t i = 0; i < nj; ++i) {
                    const double wi = w * jac[i];
                    rl[i] -= wi * r;
                    for (std::size_t j = 0; j < nj; ++j) Nl[i * nj + j] += wi * jac[j];
                }
            }
        }
        for (std::size_t i = 0; i < nj; ++i) {
            p.rhs(idx[i]) = rl[i];
            for (std::size_t j = 0; j < nj; ++j) p.N(idx[i], idx[j]) = Nl[i * nj + j];
        }
    }
    return p;
}

Eigen::MatrixXd I2(int nb) { return Eigen::MatrixXd::Identity(2 * nb, 2 * nb); }

// Constrains the shifts to have no component along the first `smooth_modes` cosines across
// the B-scans (what a smooth eye cannot tell from a smooth motion: it belongs to the eye) and
// the offsets to have no constant or linear part (the null space of the second difference),
// as penalties; a tiny ridge keeps a B-scan that no slope informs at shift 0. Solves for the
// step and returns the shifts' diagonal of the inverse (their standard errors / sigma, squared).
Eigen::VectorXd solve_step(Pass& p, int nb, int smooth_modes, Eigen::VectorXd* se_diag) {
    const double mean_diag = std::max(1e-12, p.N.diagonal().head(nb).mean());
    Eigen::MatrixXd C(nb, smooth_modes);
    Eigen::MatrixXd L(nb, 2);
    for (int b = 0; b < nb; ++b) {
        for (int k = 0; k < smooth_modes; ++k) C(b, k) = std::cos(M_PI * k * (b + 0.5) / nb);
        L(b, 0) = 1.0;
        L(b, 1) = b - 0.5 * (nb - 1);
    }
    const Eigen::MatrixXd I = Eigen::MatrixXd::Identity(nb, nb);
    const Eigen::MatrixXd Qs = Eigen::HouseholderQR<Eigen::MatrixXd>(C).householderQ() * I.leftCols(smooth_modes);
    const Eigen::MatrixXd Qo = Eigen::HouseholderQR<Eigen::MatrixXd>(L).householderQ() * I.leftCols(2);
    auto S = p.N.block(0, 0, nb, nb);
    S += 1e3 * mean_diag * Qs * Qs.transpose();
    auto O = p.N.block(nb, nb, nb, nb);
    const double mean_o = std::max(1e-12, O.diagonal().mean());
    O += 1e3 * mean_o * Qo * Qo.transpose();
    p.N.diagonal().head(nb).array() += 1e-6 * mean_diag;
    p.N.diagonal().tail(nb).array() += 1e-9 * mean_o;
    const Eigen::LDLT<Eigen::MatrixXd> ldlt(p.N);
    if (se_diag) {
        *se_diag = ldlt.solve(I2(nb)).diagonal().head(nb);
    }
    return ldlt.solve(p.rhs);
}

// The model lines of `scan` alone (no pixels), each smoothed along its A-scans by a Gaussian of
// SD `sd` A-scans (normalised over the present values within 3 SD; a missing value stays
// missing). A smoothing along the A-scans commutes with a shift along them, so the shifts are
// unchanged; what it removes is the noise of single values, which otherwise (a) makes the
// slopes, the Jacobian, mostly noise where the surface is flat and (b) favours fractional
// shifts, because a linear interpolation between two noisy values halves their variance at half
// an A-scan (docs/algorithms/onh.md, "Lateral registration").
io::Scan smoothed_lines(const io::Scan& scan, const std::vector<int>& lines, double sd) {
    io::Scan out;
    out.meta = scan.meta;
    out.bscans.resize(scan.bscans.size());
    const int nx = scan.meta.size_x;
    const int half = static_cast<int>(std::ceil(3.0 * sd));
    std::vector<double> w(static_cast<std::size_t>(half + 1));
    for (int d = 0; d <= half; ++d) w[static_cast<std::size_t>(d)] = std::exp(-0.5 * d * d / (sd * sd));
    for (std::size_t b = 0; b < scan.bscans.size(); ++b) {
        for (int k : lines) {
            const std::vector<float>* l = line_of(scan, static_cast<int>(b), k);
            if (!l) continue;
            auto& seg = out.bscans[b].seg;
            if (static_cast<int>(seg.size()) <= k) seg.resize(static_cast<std::size_t>(k + 1));
            std::vector<float> sm(l->size(), std::numeric_limits<float>::quiet_NaN());
            for (int a = 0; a < nx; ++a) {
                if (!io::is_valid((*l)[static_cast<std::size_t>(a)])) continue;
                double sw = 0.0, sv = 0.0;
                for (int d = -half; d <= half; ++d) {
                    const int x = a + d;
                    if (x < 0 || x >= nx || !io::is_valid((*l)[static_cast<std::size_t>(x)])) continue;
                    const double wd = w[static_cast<std::size_t>(std::abs(d))];
                    sw += wd;
                    sv += wd * (*l)[static_cast<std::size_t>(x)];
                }
                sm[static_cast<std::size_t>(a)] = static_cast<float>(sv / sw);
            }
            seg[static_cast<std::size_t>(k)] = std::move(sm);
        }
    }
    return out;
}

double median_of(std::vector<double> v) {
    if (v.empty()) return 0.0;
    const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
    std::nth_element(v.begin(), mid, v.end());
    return *mid;
}

}  // namespace

void LateralRegistrationParams::validate() const {
    auto require = [](bool ok, const char* field, const char* why) {
        if (!ok) throw UsageError(std::string("lateral registration: ") + field + " " + why);
    };
    require(std::isfinite(large_motion_um) && large_motion_um > 0.0, "large_motion_um",
            "must be positive");
    require(std::isfinite(max_shift_se_um) && max_shift_se_um > 0.0, "max_shift_se_um",
            "must be positive");
    require(std::isfinite(smooth_wavelength_mm) && smooth_wavelength_mm > 0.0,
            "smooth_wavelength_mm", "must be positive");
    require(std::isfinite(min_rms_um) && min_rms_um >= 0.0, "min_rms_um", "must be >= 0");
    require(min_line_fraction > 0.0 && min_line_fraction < 1.0, "min_line_fraction",
            "must be in (0, 1)");
    require(std::isfinite(smooth_wavelength_bscans) &&
                (smooth_wavelength_bscans == 0.0 || smooth_wavelength_bscans >= 4.0),
            "smooth_wavelength_bscans", "must be 0 (off) or at least 4");
    require(std::isfinite(line_smoothing_ascans) && line_smoothing_ascans >= 0.0 &&
                line_smoothing_ascans <= 16.0,
            "line_smoothing_ascans", "must be in [0, 16]");
    require(std::isfinite(step_tolerance_ascans) && step_tolerance_ascans > 0.0 &&
                step_tolerance_ascans <= 0.1,
            "step_tolerance_ascans", "must be in (0, 0.1]");
}

LateralRegistration estimate_lateral_motion(const io::Scan& scan,
                                            const LateralRegistrationParams& params) {
    params.validate();
    LateralRegistration R;
    R.enabled = params.enabled;
    R.whole_ascans = params.whole_ascans;
    R.smooth_wavelength_mm = params.smooth_wavelength_mm;
    const int nb = scan.num_bscans();
    const int nx = scan.meta.size_x;
    R.shift_um.assign(static_cast<std::size_t>(nb), 0.0);
    R.estimated.assign(static_cast<std::size_t>(nb), false);
    const double um_per_ascan = scan.meta.scale_x_mm * 1000.0;
    const double um_per_px = scan.meta.scale_z_mm * 1000.0;
    if (is_radial_scan(scan)) {
        R.notes.push_back("lateral registration: not estimated on a radial scan");
        return R;
    }
    if (nb < 2) {
        R.notes.push_back("lateral registration: not estimated on a single B-scan");
        return R;
    }
    if (nb > kMaxBscans) {
        // The normal equations are dense in 2N unknowns (the smooth-mode constraint couples
        // every B-scan): bounded time, at the cost of not estimating very dense volumes.
        R.qc_flags.push_back("lateral motion not estimated (more than 512 B-scans)");
        R.notes.push_back("lateral registration: " + std::to_string(nb) +
                          " B-scans; estimated up to 512; nothing was shifted");
        R.bscans_not_estimated = nb;
        return R;
    }
    const std::vector<int> lines = model_lines(scan);
    std::vector<char> use(static_cast<std::size_t>(nb), 0);
    int usable = 0;
    const double need = std::max(10.0, params.min_line_fraction * nx * static_cast<double>(lines.size()));
    for (int b = 0; b < nb; ++b) {
        int count = 0;
        for (int k : lines) {
            const std::vector<float>* l = line_of(scan, b, k);
            if (l) count += static_cast<int>(std::count_if(l->begin(), l->end(), [](float v) { return io::is_valid(v); }));
        }
        use[static_cast<std::size_t>(b)] = count >= need ? 1 : 0;
        usable += use[static_cast<std::size_t>(b)];
        if (!use[static_cast<std::size_t>(b)]) ++R.bscans_not_estimated;
        R.estimated[static_cast<std::size_t>(b)] = use[static_cast<std::size_t>(b)] != 0;
    }
    if (nb < 5 || usable < 5 || scan.meta.distance_mm <= 0.0) {
        R.qc_flags.push_back("lateral motion not estimated (too few B-scans with ILM and BM)");
        R.notes.push_back("lateral registration: " + std::to_string(usable) + " of " +
                          std::to_string(nb) + " B-scans hold enough ILM and BM; nothing was shifted");
        std::fill(R.estimated.begin(), R.estimated.end(), false);
        R.bscans_not_estimated = nb;
        return R;
    }
    // Cosine modes across the B-scans with a wavelength above smooth_wavelength_mm: the eye's.
    const double extent_mm = (nb - 1) * scan.meta.distance_mm;
    // Capped at smooth_wavelength_bscans B-scans (when set): on dense B-scans a shift just above
    // a cut-off of many B-scans barely changes a second difference, and the noise lands there.
    double wavelength = params.smooth_wavelength_mm;
    if (params.smooth_wavelength_bscans > 0.0) {
        wavelength = std::min(wavelength, params.smooth_wavelength_bscans * scan.meta.distance_mm);
    }
    R.smooth_wavelength_mm = wavelength;
    R.smooth_modes = std::max(2, static_cast<int>(std::ceil(2.0 * extent_mm / wavelength)));
    if (2 * R.smooth_modes > nb) {
        R.qc_flags.push_back("lateral motion not estimated (B-scans too far apart)");
        R.notes.push_back("lateral registration: the B-scans are " +
                          fixed_number(scan.meta.distance_mm * 1000.0, 0) +
                          " um apart; a shift cannot be told from the eye's shape; nothing was shifted");
        std::fill(R.estimated.begin(), R.estimated.end(), false);
        R.bscans_not_estimated = nb;
        return R;
    }
    const int smooth_modes = R.smooth_modes;
    io::Scan smoothed;
    if (params.line_smoothing_ascans > 0.0) smoothed = smoothed_lines(scan, lines, params.line_smoothing_ascans);
    const io::Scan& fit = params.line_smoothing_ascans > 0.0 ? smoothed : scan;
    Eigen::VectorXd s = Eigen::VectorXd::Zero(nb);
    Eigen::VectorXd o = Eigen::VectorXd::Zero(nb);
    Eigen::VectorXd se_diag = Eigen::VectorXd::Zero(nb);
    double scale = 0.0;  // the first passes unweighted: the shifts are not known yet
    Pass last;
    Samples samples;
    constexpr int kMaxIterations = 20;
    for (int iter = 0; iter < kMaxIterations; ++iter) {
        last = gauss_newton_pass(fit, lines, use, s, o, scale, samples);
        R.iterations = iter + 1;
        if (last.inliers < 3.0 * nb) break;
        const Eigen::VectorXd d = solve_step(last, nb, smooth_modes, nullptr);
        // At most one A-scan per step: the linearisation holds over about one A-scan.
        const double big = d.head(nb).cwiseAbs().maxCoeff();
        const double f = big > 1.0 ? 1.0 / big : 1.0;
        s += f * d.head(nb);
        o += f * d.tail(nb);
        // Tukey from the third pass on, the scale from the median absolute residual (floor
        // 0.5 px: the lines are quantised near a pixel).
        if (iter >= 2) scale = 4.685 * std::max(0.5, 1.4826 * median_of(std::move(last.abs_res)));
        if (iter >= 4 && f * big < params.step_tolerance_ascans) break;
    }
    // The standard errors from the final weights (one more pass at the solution).
    last = gauss_newton_pass(fit, lines, use, s, o, scale, samples);
    if (last.inliers >= 3.0 * nb) (void)solve_step(last, nb, smooth_modes, &se_diag);
    const bool solved = s.allFinite() && se_diag.allFinite();
    if (!solved) {
        // A failed solve: no number of it is reported or applied.
        s.setZero();
        se_diag.setZero();
    }
    R.values_used = static_cast<int>(last.inliers);
    R.values_rejected = last.rejected;
    const double sigma = last.inliers > 0.0 ? std::sqrt(last.ss / last.inliers) : 0.0;
    R.residual_rms_um = sigma * um_per_px;
    std::vector<double> se;
    double sum2 = 0.0;
    for (int b = 0; b < nb; ++b) {
        const auto bi = static_cast<std::size_t>(b);
        R.shift_um[bi] = use[bi] ? s(b) * um_per_ascan : 0.0;
        if (use[bi]) se.push_back(sigma * std::sqrt(std::max(0.0, se_diag(b))) * um_per_ascan);
        sum2 += R.shift_um[bi] * R.shift_um[bi];
        R.max_abs_shift_um = std::max(R.max_abs_shift_um, std::fabs(R.shift_um[bi]));
    }
    R.rms_shift_um = std::sqrt(sum2 / nb);
    R.shift_se_um = median_of(se);
    R.estimable = solved && R.shift_se_um <= params.max_shift_se_um;
    // Below the floor the shifts are not told from the model's own error on a still eye:
    // nothing is moved (a still scan stays as read).
    R.applied = params.enabled && R.estimable && R.rms_shift_um >= params.min_rms_um;
    if (!R.estimable) {
        R.qc_flags.push_back("lateral motion not estimable (the surfaces hold too little slope)");
    }
    const std::string what = R.applied                ? "removed"
                             : !params.enabled        ? "not removed (registration off)"
                             : !R.estimable           ? "not removed (not estimable)"
                                                      : "not removed (below " + fixed_number(params.min_rms_um, 0) + " um RMS)";
    R.notes.push_back("lateral motion between B-scans " + what + ": RMS " +
                      fixed_number(R.rms_shift_um, 1) + " um, largest " +
                      fixed_number(R.max_abs_shift_um, 1) + " um, standard error " +
                      fixed_number(R.shift_se_um, 1) + " um per B-scan");
    if (R.estimable && R.rms_shift_um > params.large_motion_um) {
        R.qc_flags.push_back(params.enabled ? "large lateral motion between B-scans (registered)"
                                            : "large lateral motion between B-scans (not registered)");
    }
    if (R.bscans_not_estimated > 0) {
        R.qc_flags.push_back("lateral motion not estimated in some B-scans (too few line values)");
    }
    return R;
}

void apply_lateral_registration(io::Scan& scan, const LateralRegistration& registration) {
    if (!registration.applied) return;
    const double um_per_ascan = scan.meta.scale_x_mm * 1000.0;
    for (int b = 0; b < scan.num_bscans(); ++b) {
        const double raw = -registration.shift_um[static_cast<std::size_t>(b)] / um_per_ascan;
        const double dx = registration.whole_ascans ? std::round(raw) : raw;
        io::BScan& bs = scan.bscans[static_cast<std::size_t>(b)];
        // The lines by the shift itself, or by whole A-scans (whole_ascans); below 1e-3 A-scans
        // nothing moves.
        if (std::fabs(dx) >= 1e-3) {
            std::vector<float> pixels;
            pixels.swap(bs.pixels);
            io::shift_bscan(bs, scan.meta.size_x, scan.meta.size_z, 0.0, dx);
            pixels.swap(bs.pixels);
        }
        // The pixels by whole A-scans: a fractional shift blends neighbouring A-scans, which
        // changes the speckle's statistics in that B-scan alone and moves the level set.
        // (Measured on a 97 x 256 cupped phantom with 30 um of jitter, level-set ILM: cup
        // volume -4.6 % with fractional pixel shifts, -3.3 % with whole ones; still -1.5 %.)
        const double whole = std::round(dx);
        if (whole != 0.0 && !bs.pixels.empty()) {
            std::vector<std::vector<float>> seg;
            seg.swap(bs.seg);
            io::shift_bscan(bs, scan.meta.size_x, scan.meta.size_z, 0.0, whole);
            seg.swap(bs.seg);
        }
    }
}

LateralRegistration register_laterally(io::Scan& scan, const LateralRegistrationParams& params) {
    LateralRegistration r = estimate_lateral_motion(scan, params);
    apply_lateral_registration(scan, r);
    return r;
}

nlohmann::ordered_json lateral_registration_json(const LateralRegistration& l) {
    // Per B-scan (from 0): the lateral shift estimated (+ = the B-scan lay towards higher
    // A-scans than the eye) and removed when applied.
    nlohmann::ordered_json lat;
    lat["applied"] = l.applied;
    lat["estimable"] = l.estimable;
    lat["model"] =
        "the device ILM and BM lines smoothest across B-scans: second differences across "
        "B-scans of the shifted lines (robust least squares, per-B-scan depth offsets free); "
        "shifts varying slower than smooth_wavelength_mm across B-scans belong to the eye "
        "(docs/algorithms/onh.md)";
    lat["smooth_wavelength_mm"] = l.smooth_wavelength_mm;
    lat["smooth_modes"] = l.smooth_modes;
    lat["rms_shift_um"] = l.rms_shift_um;
    lat["max_abs_shift_um"] = l.max_abs_shift_um;
    lat["shift_se_um"] = l.shift_se_um;
    lat["residual_rms_um"] = l.residual_rms_um;
    lat["values_used"] = l.values_used;
    lat["values_rejected"] = l.values_rejected;
    lat["bscans_not_estimated"] = l.bscans_not_estimated;
    put_shifts(lat, l.shift_um, l.estimated);
    return lat;
}

}  // namespace octshape::retina
