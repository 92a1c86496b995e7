#pragma once
// Cohort statistics (docs/stats.md): descriptive summaries (mean, SD, min, max)
// and the test-retest intraclass correlation ICC(2,1) with its 95 % confidence interval, plus
// the special functions they need (regularised incomplete beta, F distribution).
//
// ICC(2,1) is Shrout & Fleiss's (1979) case 2, single measurement: two-way random effects,
// absolute agreement (McGraw & Wong 1996: ICC(A,1)). The thesis reports it for repeated scans
// (Tables 7.1 and 8.1). The numbers agree with R's psych::ICC(x, lmer = FALSE), row "ICC2".

#include <Eigen/Core>
#include <cstddef>
#include <limits>
#include <vector>

namespace octshape::retina {

// ---- special functions ---------------------------------------------------------------------

// Regularised incomplete beta I_x(a, b) = B(x; a, b) / B(a, b) for a, b > 0, x in [0, 1]
// (continued fraction, modified Lentz; relative accuracy ~1e-14). Throws DataError for a, b or
// x outside the domain, AnalysisError if the fraction does not converge (a, b beyond ~1e9).
[[nodiscard]] double incomplete_beta(double a, double b, double x);

// The x in [0, 1] with I_x(a, b) = p, p in [0, 1] (safeguarded Newton on a bracket, converged
// to ~1e-15 in x). Throws DataError for a or b outside the domain, UsageError for p.
[[nodiscard]] double incomplete_beta_inverse(double a, double b, double p);

// F distribution with d1, d2 > 0 degrees of freedom (non-integer allowed: the ICC confidence
// interval uses a Satterthwaite df): P(F <= f), P(F > f) (computed directly, accurate for
// small tail probabilities) and the quantile f with P(F <= f) = p (UsageError for p outside
// [0, 1]).
[[nodiscard]] double f_cdf(double f, double d1, double d2);
[[nodiscard]] double f_upper_tail(double f, double d1, double d2);
[[nodiscard]] double f_quantile(double p, double d1, double d2);

// ---- descriptive statistics ----------------------------------------------------------------

struct Summary {
    std::size_t n = 0;  // number of values (missing values are not passed in)
    double mean = std::numeric_limits<double>::quiet_NaN();
    double sd = std::numeric_limits<double>::quiet_NaN();  // sample SD (n - 1); NaN if n < 2
    double min = std::numeric_limits<double>::quiet_NaN();
    double max = std::numeric_limits<double>::quiet_NaN();
};

// n, mean, SD (denominator n - 1, two-pass), min, max. Empty input -> n = 0, all NaN.
// Throws DataError on a non-finite value.
[[nodiscard]] Summary summarise(const std::vector<double>& values);

// ---- ICC(2,1) ------------------------------------------------------------------------------

struct IccParams {
    double confidence = 0.95;  // two-sided level of the interval (alpha = 1 - confidence)
    // Throws UsageError naming the bad field.
    void validate() const;
};

struct IccResult {
    int n = 0;  // targets (eyes), rows of the ratings matrix
    int k = 0;  // measurements per target (scans), columns
    double icc = std::numeric_limits<double>::quiet_NaN();    // ICC(2,1)
    double lower = std::numeric_limits<double>::quiet_NaN();  // confidence bounds
    double upper = std::numeric_limits<double>::quiet_NaN();
    // Two-way ANOVA mean squares (Shrout & Fleiss Table 2): rows (BMS), columns (JMS),
    // residual (EMS), within rows (WMS).
    double ms_rows = std::numeric_limits<double>::quiet_NaN();
    double ms_cols = std::numeric_limits<double>::quiet_NaN();
    double ms_error = std::numeric_limits<double>::quiet_NaN();
    double ms_within = std::numeric_limits<double>::quiet_NaN();
    // F = BMS / EMS on (n - 1, (n - 1)(k - 1)) df tests ICC = 0; p its upper tail.
    double f = std::numeric_limits<double>::quiet_NaN();
    int df1 = 0;
    int df2 = 0;
    double p = std::numeric_limits<double>::quiet_NaN();
    double df_satterthwaite = std::numeric_limits<double>::quiet_NaN();  // v of the CI
};

// ICC(2,1) of an n x k matrix (rows = targets, columns = measurement occasions; complete, all
// finite), n >= 2, k >= 2. When every value is equal the ICC is undefined: icc and the bounds
// are NaN. Throws DataError on a bad shape or a non-finite value.
[[nodiscard]] IccResult icc_2_1(const Eigen::MatrixXd& ratings, const IccParams& params = {});

}  // namespace octshape::retina
