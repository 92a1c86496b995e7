#include "octshape/retina/stats.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "octshape/error.h"

namespace octshape::retina {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// log B(a, b) through lgamma (std::lgamma is exact enough here: the ICC dfs are < 1e6).
double log_beta(double a, double b) { return std::lgamma(a) + std::lgamma(b) - std::lgamma(a + b); }

// Continued fraction of I_x(a, b) (Numerical Recipes 3rd ed. §6.4 "betacf", modified Lentz):
// I_x(a,b) = x^a (1-x)^b / (a B(a,b)) * 1 / (1 + d1 / (1 + d2 / (1 + ...))), converging fast
// for x < (a + 1) / (a + b + 2).
double beta_continued_fraction(double a, double b, double x) {
    constexpr int kMaxIterations = 100000;
    constexpr double kEps = 1e-16;
    constexpr double kTiny = 1e-300;
    const double qab = a + b;
    const double qap = a + 1.0;
    const double qam = a - 1.0;
    double c = 1.0;
    double d = 1.0 - qab * x / qap;
    if (std::fabs(d) < kTiny) d = kTiny;
    d = 1.0 / d;
    double h = d;
    for (int m = 1; m <= kMaxIterations; ++m) {
        const double m2 = 2.0 * m;
        double aa = m * (b - m) * x / ((qam + m2) * (a + m2));  // even step d_{2m}
        d = 1.0 + aa * d;
        if (std::fabs(d) < kTiny) d = kTiny;
        c = 1.0 + aa / c;
        if (std::fabs(c) < kTiny) c = kTiny;
        d = 1.0 / d;
        h *= d * c;
        aa = -(a + m) * (qab + m) * x / ((a + m2) * (qap + m2));  // odd step d_{2m+1}
        d = 1.0 + aa * d;
        if (std::fabs(d) < kTiny) d = kTiny;
        c = 1.0 + aa / c;
        if (std::fabs(c) < kTiny) c = kTiny;
        d = 1.0 / d;
        const double del = d * c;
        h *= del;
        if (std::fabs(del - 1.0) <= kEps) return h;
    }
    throw AnalysisError("incomplete_beta: continued fraction did not converge (a = " +
                        std::to_string(a) + ", b = " + std::to_string(b) + ")");
}

void check_beta_args(double a, double b, const char* what) {
    if (!(a > 0.0) || !(b > 0.0) || !std::isfinite(a) || !std::isfinite(b)) {
        throw DataError(std::string(what) + ": a and b must be finite and > 0");
    }
}

}  // namespace

double incomplete_beta(double a, double b, double x) {
    check_beta_args(a, b, "incomplete_beta");
    if (!(x >= 0.0 && x <= 1.0)) throw DataError("incomplete_beta: x must be in [0, 1]");
    if (x == 0.0) return 0.0;
    if (x == 1.0) return 1.0;
    const double front = std::exp(a * std::log(x) + b * std::log1p(-x) - log_beta(a, b));
    if (x < (a + 1.0) / (a + b + 2.0)) return front * beta_continued_fraction(a, b, x) / a;
    // Symmetry I_x(a, b) = 1 - I_{1-x}(b, a): the fraction converges on the other side.
    return 1.0 - front * beta_continued_fraction(b, a, 1.0 - x) / b;
}

double incomplete_beta_inverse(double a, double b, double p) {
    check_beta_args(a, b, "incomplete_beta_inverse");
    if (!(p >= 0.0 && p <= 1.0)) {
        throw UsageError("incomplete_beta_inverse: p must be in [0, 1]");
    }
    if (p == 0.0) return 0.0;
    if (p == 1.0) return 1.0;
    const double lb = log_beta(a, b);
    // I is increasing in x: keep a bracket [lo, hi] around the root, take Newton steps (the
    // derivative is the Beta density) and fall back to bisection when a step leaves it.
    double lo = 0.0;
    double hi = 1.0;
    double x = std::clamp(a / (a + b), 1e-6, 1.0 - 1e-6);  // the mean: a start inside (0, 1)
    for (int it = 0; it < 1000; ++it) {
        const double f = incomplete_beta(a, b, x) - p;
        if (f == 0.0) return x;
        if (f < 0.0) {
            lo = x;
        } else {
            hi = x;
        }
        if (hi - lo <= 2.0 * std::numeric_limits<double>::epsilon() * hi) return x;  // bracket
        const double density = std::exp((a - 1.0) * std::log(x) + (b - 1.0) * std::log1p(-x) - lb);
        double next = x - f / density;
        if (!(next > lo && next < hi) || !std::isfinite(next)) next = 0.5 * (lo + hi);
        // Converged when a step moves x by at most 2 ulps.
        if (std::fabs(next - x) <= 2.0 * std::numeric_limits<double>::epsilon() *
                                       std::max(x, std::numeric_limits<double>::min())) {
            return next;
        }
        x = next;
    }
    return x;
}

double f_cdf(double f, double d1, double d2) {
    if (!(f >= 0.0)) return 0.0;
    if (std::isinf(f)) return 1.0;
    // P(F <= f) = I_{d1 f / (d1 f + d2)}(d1/2, d2/2).
    return incomplete_beta(0.5 * d1, 0.5 * d2, d1 * f / (d1 * f + d2));
}

double f_upper_tail(double f, double d1, double d2) {
    if (!(f >= 0.0)) return 1.0;
    if (std::isinf(f)) return 0.0;
    // P(F > f) = I_{d2 / (d2 + d1 f)}(d2/2, d1/2): no cancellation for small tails.
    return incomplete_beta(0.5 * d2, 0.5 * d1, d2 / (d2 + d1 * f));
}

double f_quantile(double p, double d1, double d2) {
    if (!(p >= 0.0 && p <= 1.0)) throw UsageError("f_quantile: p must be in [0, 1]");
    if (p == 0.0) return 0.0;
    if (p == 1.0) return std::numeric_limits<double>::infinity();
    // With y = d2 / (d2 + d1 f) ~ Beta(d2/2, d1/2): P(F <= f) = 1 - I_y(d2/2, d1/2), so
    // f = d2 (1 - y) / (d1 y) with y = I^-1(d2/2, d1/2; 1 - p). Working in y keeps the upper
    // quantiles (p near 1, the ones confidence intervals need) accurate.
    const double y = incomplete_beta_inverse(0.5 * d2, 0.5 * d1, 1.0 - p);
    return d2 * (1.0 - y) / (d1 * y);
}

Summary summarise(const std::vector<double>& values) {
    Summary s;
    s.n = values.size();
    if (values.empty()) return s;
    double sum = 0.0;
    s.min = values.front();
    s.max = values.front();
    for (const double v : values) {
        if (!std::isfinite(v)) throw DataError("summarise: non-finite value");
        sum += v;
        s.min = std::min(s.min, v);
        s.max = std::max(s.max, v);
    }
    s.mean = sum / static_cast<double>(s.n);
    if (s.n >= 2) {
        double ss = 0.0;  // two-pass: no cancellation for large means
        for (const double v : values) ss += (v - s.mean) * (v - s.mean);
        s.sd = std::sqrt(ss / static_cast<double>(s.n - 1));
    }
    return s;
}

void IccParams::validate() const {
    if (!(confidence > 0.0 && confidence < 1.0)) {
        throw UsageError("icc: confidence must be in (0, 1)");
    }
}

IccResult icc_2_1(const Eigen::MatrixXd& x, const IccParams& params) {
    params.validate();
    if (x.rows() < 2 || x.cols() < 2) {
        throw DataError("icc_2_1: need at least 2 targets and 2 measurements");
    }
    if (!x.allFinite()) throw DataError("icc_2_1: non-finite rating");
    IccResult r;
    r.n = static_cast<int>(x.rows());
    r.k = static_cast<int>(x.cols());
    const double n = r.n;
    const double k = r.k;
    const double grand = x.mean();
    const Eigen::VectorXd row_mean = x.rowwise().mean();
    const Eigen::RowVectorXd col_mean = x.colwise().mean();
    // Two-way ANOVA without replication (Shrout & Fleiss 1979, Table 2).
    const double ss_rows = k * (row_mean.array() - grand).square().sum();
    const double ss_cols = n * (col_mean.array() - grand).square().sum();
    double ss_error = 0.0;
    for (Eigen::Index i = 0; i < x.rows(); ++i) {
        for (Eigen::Index j = 0; j < x.cols(); ++j) {
            const double e = x(i, j) - row_mean(i) - col_mean(j) + grand;
            ss_error += e * e;
        }
    }
    r.ms_rows = ss_rows / (n - 1.0);                       // BMS
    r.ms_cols = ss_cols / (k - 1.0);                       // JMS
    r.ms_error = ss_error / ((n - 1.0) * (k - 1.0));       // EMS
    r.ms_within = (ss_cols + ss_error) / (n * (k - 1.0));  // WMS
    const double bms = r.ms_rows;
    const double jms = r.ms_cols;
    const double ems = r.ms_error;
    r.df1 = r.n - 1;
    r.df2 = (r.n - 1) * (r.k - 1);
    // ICC(2,1) = (BMS - EMS) / (BMS + (k-1) EMS + k (JMS - EMS) / n)   (S&F Eq. 2)
    const double denom = bms + (k - 1.0) * ems + k * (jms - ems) / n;
    if (!(denom > 0.0)) return r;  // all ratings equal: undefined
    r.icc = (bms - ems) / denom;
    if (!(ems > 0.0)) {
        // No residual variation: F is infinite. With no rater variation either (every repeat
        // identical, the targets differing) the ICC is exactly 1 and the interval is [1, 1], the
        // limit of Eq. 8-9 as EMS and JMS go to 0 (what psych::ICC reports); otherwise the
        // interval is degenerate and stays NaN.
        r.f = std::numeric_limits<double>::infinity();
        r.p = 0.0;
        if (!(jms > 0.0)) r.lower = r.upper = r.icc;
        return r;
    }
    r.f = bms / ems;
    r.p = f_upper_tail(r.f, r.df1, r.df2);
    // Confidence interval (S&F 1979 Eq. 8-9; McGraw & Wong 1996 Table 7, case 2A) with the
    // Satterthwaite degrees of freedom v of the denominator's linear combination of MS.
    const double icc = r.icc;
    const double fj = jms / ems;
    const double a = n * (1.0 + (k - 1.0) * icc) - k * icc;
    const double vn = (k - 1.0) * (n - 1.0) * std::pow(k * icc * fj + a, 2);
    const double vd = (n - 1.0) * k * k * icc * icc * fj * fj + a * a;
    r.df_satterthwaite = vn / vd;
    const double v = r.df_satterthwaite;
    const double q = 1.0 - 0.5 * (1.0 - params.confidence);
    if (!(v > 0.0) || !std::isfinite(v)) return r;
    const double f_star_u = f_quantile(q, n - 1.0, v);  // F*_{1-alpha/2}(n-1, v)
    const double f_star_l = f_quantile(q, v, n - 1.0);  // F*_{1-alpha/2}(v, n-1)
    const double c = k * jms + (k * n - k - n) * ems;
    r.lower = n * (bms - f_star_u * ems) / (f_star_u * c + n * bms);
    r.upper = n * (f_star_l * bms - ems) / (c + n * f_star_l * bms);
    return r;
}

}  // namespace octshape::retina
