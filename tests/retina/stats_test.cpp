// Special functions and ICC(2,1) (libretina stats.h) against values known independently of the
// code: closed forms, finite sums, published tables and R 4.2 (pbeta/qf/qt, psych::ICC).

#include "octshape/retina/stats.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <numbers>
#include <random>
#include <stdexcept>

#include "octshape/error.h"

namespace octshape::retina {
namespace {

// ---- regularised incomplete beta -----------------------------------------------------------

TEST(IncompleteBeta, ClosedForms) {
    // I_x(a, 1) = x^a, I_x(1, b) = 1 - (1 - x)^b, I_x(1/2, 1/2) = (2/pi) asin(sqrt x).
    for (const double x : {1e-8, 0.01, 0.2, 0.5, 0.77, 0.999}) {
        for (const double a : {0.3, 1.0, 2.5, 17.0}) {
            EXPECT_NEAR(incomplete_beta(a, 1.0, x), std::pow(x, a), 1e-13) << a << " " << x;
            EXPECT_NEAR(incomplete_beta(1.0, a, x), -std::expm1(a * std::log1p(-x)), 1e-13)
                << a << " " << x;
        }
        EXPECT_NEAR(incomplete_beta(0.5, 0.5, x), 2.0 / std::numbers::pi * std::asin(std::sqrt(x)),
                    1e-13);
    }
    // Symmetric parameters at x = 1/2.
    for (const double a : {0.3, 7.0, 150.0}) EXPECT_NEAR(incomplete_beta(a, a, 0.5), 0.5, 1e-13);
    EXPECT_EQ(incomplete_beta(2.0, 3.0, 0.0), 0.0);
    EXPECT_EQ(incomplete_beta(2.0, 3.0, 1.0), 1.0);
}

TEST(IncompleteBeta, BinomialTailSum) {
    // I_p(k, n - k + 1) = P(Binomial(n, p) >= k): a finite sum computed here term by term.
    const int n = 40;
    const double p = 0.3;
    for (const int k : {1, 5, 13, 25, 39}) {
        double sum = 0.0;
        for (int j = k; j <= n; ++j) {
            double c = 1.0;  // C(n, j) as a product (exact to rounding)
            for (int i = 1; i <= j; ++i) c = c * (n - j + i) / i;
            sum += c * std::pow(p, j) * std::pow(1.0 - p, n - j);
        }
        EXPECT_NEAR(incomplete_beta(k, n - k + 1, p), sum, 1e-13 * std::max(1.0, sum)) << k;
    }
}

TEST(IncompleteBeta, AgreesWithR) {
    // R 4.2.2: pbeta(0.3, 2.5, 7.25) = 0.66048227358190736.
    EXPECT_NEAR(incomplete_beta(2.5, 7.25, 0.3), 0.66048227358190736, 1e-13);
    // qbeta(0.01, 0.7, 40) = 3.0428816517929188e-05.
    EXPECT_NEAR(incomplete_beta_inverse(0.7, 40.0, 0.01), 3.0428816517929188e-05, 1e-17);
}

TEST(IncompleteBeta, InverseRoundTrip) {
    // The best any double x can do is p to within density(x) * |x| * eps per ulp of x (where
    // the density is steep, e.g. b < 1 near x = 1, that exceeds 1e-12): allow 1e-12 relative
    // plus 8 ulps of x times the Beta density there.
    for (const double a : {0.4, 1.0, 2.5, 30.0, 400.0}) {
        for (const double b : {0.6, 1.0, 7.5, 90.0}) {
            for (const double p : {1e-10, 1e-4, 0.025, 0.3, 0.5, 0.9, 0.975, 0.9999}) {
                const double x = incomplete_beta_inverse(a, b, p);
                EXPECT_GE(x, 0.0);
                EXPECT_LE(x, 1.0);
                const double density =
                    std::exp((a - 1) * std::log(x) + (b - 1) * std::log1p(-x) + std::lgamma(a + b) -
                             std::lgamma(a) - std::lgamma(b));
                const double tol = 1e-12 * std::max(p, 1e-3) +
                                   8.0 * std::numeric_limits<double>::epsilon() * x * density;
                EXPECT_NEAR(incomplete_beta(a, b, x), p, tol) << a << " " << b << " " << p;
            }
        }
    }
    EXPECT_EQ(incomplete_beta_inverse(2.0, 3.0, 0.0), 0.0);
    EXPECT_EQ(incomplete_beta_inverse(2.0, 3.0, 1.0), 1.0);
}

// Bad arguments are octshape's typed errors (exit 65 / 64 / 69), not std::domain_error (70).
TEST(IncompleteBeta, RejectsBadArgumentsWithTypedErrors) {
    EXPECT_THROW((void)incomplete_beta(0.0, 1.0, 0.5), DataError);
    EXPECT_THROW((void)incomplete_beta(1.0, -1.0, 0.5), DataError);
    EXPECT_THROW((void)incomplete_beta(1.0, 1.0, 1.5), DataError);
    EXPECT_THROW((void)incomplete_beta(1.0, 1.0, std::nan("")), DataError);
    EXPECT_THROW((void)incomplete_beta_inverse(1.0, 1.0, -0.1), UsageError);
    EXPECT_THROW((void)f_quantile(1.5, 2.0, 3.0), UsageError);
    // At x = a / (a + b) the fraction needs ~sqrt(a) terms: at a = b = 1e14 more than its
    // 100000 (~1.4 ms).
    EXPECT_THROW((void)incomplete_beta(1e14, 1e14, 0.5), AnalysisError);
}

// ---- F distribution ------------------------------------------------------------------------

TEST(FDistribution, TwoNumeratorDfClosedForm) {
    // F(2, d2): P(F <= f) = 1 - (1 + 2 f / d2)^(-d2/2), so f_p = (d2/2) ((1-p)^(-2/d2) - 1).
    for (const double d2 : {3.0, 7.5, 40.0}) {
        for (const double p : {0.05, 0.5, 0.95, 0.975}) {
            const double f = 0.5 * d2 * (std::pow(1.0 - p, -2.0 / d2) - 1.0);
            EXPECT_NEAR(f_quantile(p, 2.0, d2), f, 1e-11 * f) << d2 << " " << p;
            EXPECT_NEAR(f_cdf(f, 2.0, d2), p, 1e-13);
            EXPECT_NEAR(f_upper_tail(f, 2.0, d2), 1.0 - p, 1e-13);
        }
    }
}

TEST(FDistribution, StudentTRelationAndTables) {
    // F(1, v) = t(v)^2: t_{0.975, 10} = 2.2281388519862739 (R qt; printed tables: 2.228).
    const double t = 2.2281388519862739;
    EXPECT_NEAR(f_quantile(0.95, 1.0, 10.0), t * t, 1e-10);
    // Printed F tables (e.g. NIST/SEMATECH e-Handbook 1.3.6.7.2): F_0.95(5, 15) = 2.901.
    EXPECT_NEAR(f_quantile(0.95, 5.0, 15.0), 2.901, 5e-4);
    // R: qf(0.95, 5, 15) = 2.9012945362361577, qf(0.975, 5, 15) = 3.5764153492790602,
    // qf(0.975, 17.3, 5) = 6.3752908400707762 (non-integer df, as the ICC interval needs),
    // pf(2.5, 3.5, 12.25, lower.tail = FALSE) = 0.10217245650639201.
    EXPECT_NEAR(f_quantile(0.95, 5.0, 15.0), 2.9012945362361577, 1e-11);
    EXPECT_NEAR(f_quantile(0.975, 5.0, 15.0), 3.5764153492790602, 1e-11);
    EXPECT_NEAR(f_quantile(0.975, 17.3, 5.0), 6.3752908400707762, 1e-10);
    EXPECT_NEAR(f_upper_tail(2.5, 3.5, 12.25), 0.10217245650639201, 1e-14);
}

// ---- descriptive statistics ----------------------------------------------------------------

TEST(Summarise, HandComputed) {
    // 2, 4, 4, 4, 5, 5, 7, 9: mean 5, squared deviations sum 32, SD sqrt(32/7).
    const Summary s = summarise({2, 4, 4, 4, 5, 5, 7, 9});
    EXPECT_EQ(s.n, 8U);
    EXPECT_DOUBLE_EQ(s.mean, 5.0);
    EXPECT_NEAR(s.sd, std::sqrt(32.0 / 7.0), 1e-15);
    EXPECT_EQ(s.min, 2.0);
    EXPECT_EQ(s.max, 9.0);
    // A large common offset does not cost precision (two-pass SD).
    const Summary t =
        summarise({1e9 + 2, 1e9 + 4, 1e9 + 4, 1e9 + 4, 1e9 + 5, 1e9 + 5, 1e9 + 7, 1e9 + 9});
    EXPECT_NEAR(t.sd, std::sqrt(32.0 / 7.0), 1e-12);
    const Summary one = summarise({3.5});
    EXPECT_EQ(one.n, 1U);
    EXPECT_EQ(one.mean, 3.5);
    EXPECT_TRUE(std::isnan(one.sd));
    const Summary none = summarise({});
    EXPECT_EQ(none.n, 0U);
    EXPECT_TRUE(std::isnan(none.mean));
    EXPECT_THROW((void)summarise({1.0, std::nan("")}), DataError);
}

// ---- ICC(2,1) ------------------------------------------------------------------------------

// Shrout & Fleiss (1979) Table 1: 6 targets rated by 4 judges.
Eigen::MatrixXd shrout_fleiss() {
    Eigen::MatrixXd m(6, 4);
    m << 9, 2, 5, 8,  //
        6, 1, 3, 2,   //
        8, 4, 6, 8,   //
        7, 1, 2, 6,   //
        10, 5, 6, 9,  //
        6, 2, 4, 7;
    return m;
}

TEST(Icc21, ShroutFleissPublishedExample) {
    const IccResult r = icc_2_1(shrout_fleiss());
    EXPECT_EQ(r.n, 6);
    EXPECT_EQ(r.k, 4);
    // Their Table 2 (two decimals): BMS 11.24, WMS 6.26, JMS 32.49, EMS 1.02.
    EXPECT_NEAR(r.ms_rows, 11.24, 0.005);
    EXPECT_NEAR(r.ms_within, 6.26, 0.005);
    EXPECT_NEAR(r.ms_cols, 32.49, 0.005);
    EXPECT_NEAR(r.ms_error, 1.02, 0.005);
    // Their Table 4: ICC(2,1) = .29.
    EXPECT_NEAR(r.icc, 0.29, 0.005);
    // Exact sums of squares (hand-checkable: SSR = 56.2083, SSC = 97.4583, SSE = 15.2917) and
    // R psych::ICC(x, lmer = FALSE) row ICC2: 0.28976377952755922, F 11.027247956403272 on
    // (5, 15), p 1.3456651648433693e-04, 95 % CI [0.018786513374712047, 0.7610843696489531].
    EXPECT_NEAR(r.ms_rows * 5, 56.208333333333343, 1e-12);
    EXPECT_NEAR(r.ms_cols * 3, 97.458333333333286, 1e-12);
    EXPECT_NEAR(r.ms_error * 15, 15.291666666666666, 1e-12);
    EXPECT_NEAR(r.icc, 0.28976377952755922, 1e-14);
    EXPECT_NEAR(r.f, 11.027247956403272, 1e-11);
    EXPECT_EQ(r.df1, 5);
    EXPECT_EQ(r.df2, 15);
    EXPECT_NEAR(r.p, 1.3456651648433693e-04, 1e-15);
    EXPECT_NEAR(r.lower, 0.018786513374712047, 1e-10);
    EXPECT_NEAR(r.upper, 0.7610843696489531, 1e-10);
}

TEST(Icc21, ConstantSessionOffsetIsPenalised) {
    // Targets 1, 2, 3 measured twice, the second time +1 exactly: EMS = 0,
    // BMS = 2 * var(1, 2, 3) = 2, JMS = 3 * var(0, 1) = 1.5,
    // ICC(2,1) = BMS / (BMS + k JMS / n) = 2 / (2 + 2 * 1.5 / 3) = 2/3 (absolute agreement).
    Eigen::MatrixXd m(3, 2);
    m << 1, 2, 2, 3, 3, 4;
    const IccResult r = icc_2_1(m);
    EXPECT_NEAR(r.ms_rows, 2.0, 1e-15);
    EXPECT_NEAR(r.ms_cols, 1.5, 1e-15);
    EXPECT_NEAR(r.ms_error, 0.0, 1e-15);
    EXPECT_NEAR(r.icc, 2.0 / 3.0, 1e-15);
    EXPECT_TRUE(std::isnan(r.lower));  // degenerate interval: no residual variance
}

TEST(Icc21, PerfectAgreementAndUndefined) {
    Eigen::MatrixXd m(4, 3);
    m << 1, 1, 1, 5, 5, 5, 2, 2, 2, 7, 7, 7;
    EXPECT_DOUBLE_EQ(icc_2_1(m).icc, 1.0);
    const IccResult c = icc_2_1(Eigen::MatrixXd::Constant(4, 2, 3.0));
    EXPECT_TRUE(std::isnan(c.icc));
}

TEST(Icc21, InvariantUnderAffineMapsAndRowOrder) {
    const Eigen::MatrixXd m = shrout_fleiss();
    const IccResult a = icc_2_1(m);
    const IccResult b = icc_2_1((m.array() * 0.01 + 100.0).matrix());
    Eigen::MatrixXd rev = m.colwise().reverse();  // targets in reverse order
    const IccResult c = icc_2_1(rev);
    for (const IccResult* r : {&b, &c}) {
        EXPECT_NEAR(r->icc, a.icc, 1e-11);
        EXPECT_NEAR(r->lower, a.lower, 1e-9);
        EXPECT_NEAR(r->upper, a.upper, 1e-9);
    }
}

TEST(Icc21, RecoversThePopulationIccOfALargeSample) {
    // x_ij = t_i + c_j + e_ij with SD 2 (targets), 0.5 (sessions), 1 (error): population
    // ICC(2,1) = 4 / (4 + 0.25 + 1) = 0.7619. n = 3000 targets, k = 3: the estimate's SD is
    // about 0.01 here, but the 3 session effects c_j are one draw, so the realised session
    // variance can be far from 0.25: the session part is taken as realised (sample variance of
    // the drawn c_j), leaving sampling error of the target and error variances (~1 %).
    std::mt19937_64 rng(12345);
    std::normal_distribution<double> z(0.0, 1.0);
    const int n = 3000;
    const int k = 3;
    Eigen::VectorXd c(k);
    for (int j = 0; j < k; ++j) c(j) = 0.5 * z(rng);
    Eigen::MatrixXd m(n, k);
    for (int i = 0; i < n; ++i) {
        const double t = 2.0 * z(rng);
        for (int j = 0; j < k; ++j) m(i, j) = t + c(j) + z(rng);
    }
    const double var_c = (c.array() - c.mean()).square().sum() / (k - 1);
    const IccResult r = icc_2_1(m);
    EXPECT_NEAR(r.icc, 4.0 / (4.0 + var_c + 1.0), 0.03);
    EXPECT_LT(r.lower, r.icc);
    EXPECT_GT(r.upper, r.icc);
}

TEST(Icc21, RejectsBadInput) {
    EXPECT_THROW((void)icc_2_1(Eigen::MatrixXd::Zero(1, 3)), octshape::DataError);
    EXPECT_THROW((void)icc_2_1(Eigen::MatrixXd::Zero(3, 1)), octshape::DataError);
    Eigen::MatrixXd m = shrout_fleiss();
    m(2, 1) = std::nan("");
    EXPECT_THROW((void)icc_2_1(m), octshape::DataError);
    IccParams p;
    p.confidence = 1.0;
    EXPECT_THROW((void)icc_2_1(shrout_fleiss(), p), UsageError);
}

}  // namespace
}  // namespace octshape::retina
