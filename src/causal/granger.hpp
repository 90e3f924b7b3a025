#pragma once
// Granger causality (SPEC section 4): the bivariate sum-of-squared-residuals F test with a
// constant, rows never lagged across an episode boundary, multiple-testing control.
#include <string>
#include <vector>

namespace cd {

struct GrangerTest {
  double f_stat = 0;
  double p_value = 1;
  int df_num = 0;  // L
  int df_den = 0;  // n - 2L - 1 (bivariate); fewer with conditioning variables
  long rows = 0;   // n: rows of the regression after lagging
  // The effect size: (SSR_r - SSR_u) / SSR_r, the share of the variance the restricted model
  // leaves that the candidate's lags explain. Unlike p, it does not grow with n.
  double partial_r2 = 0;
};

// One series per episode for the target y and the candidate x (equal lengths per episode).
// Restricted model: y_t on a constant and y_{t-1..t-L}; unrestricted: plus x_{t-1..t-L}.
// With `conditioning` (each a set of per-episode series), both models also hold L lags of
// every conditioning variable (the conditional, multivariate variant).
// Throws DataError when there are too few rows for the test.
GrangerTest granger_f_test(const std::vector<std::vector<double>>& y,
                           const std::vector<std::vector<double>>& x, int lags,
                           const std::vector<std::vector<std::vector<double>>>& conditioning = {});

// The conditional test of every candidate: candidate i given the lags of all the others, the
// numbers granger_f_test(y, candidates[i], lags, {the others}) gives, from one least-squares fit
// of the full model (the restricted SSR of each from the Wald form of dropping its block), so
// that 128 latents cost one regression, not 256. A rank-deficient design falls back to one fit
// per candidate. Throws DataError like granger_f_test.
std::vector<GrangerTest> conditional_f_tests(
    const std::vector<std::vector<double>>& y,
    const std::vector<std::vector<std::vector<double>>>& candidates, int lags);

// Adjusted p-values: "none" (as given), "bonferroni" (p * m, at most 1), "bh"
// (Benjamini-Hochberg step-up, monotone, at most 1). A variable is selected when its adjusted
// p-value is <= alpha. Throws ConfigError for another method name.
std::vector<double> adjust_p_values(const std::vector<double>& p, const std::string& method);

// A named variable, one series per episode.
struct NamedSeries {
  std::string name;
  std::vector<std::vector<double>> episodes;
};

struct GrangerResult {
  std::string variable;
  GrangerTest test;
  double p_adjusted = 1;  // after the correction
  bool selected = false;  // p_adjusted <= alpha
};

// Tests every candidate against the target y (in the candidates' order), adjusts the p-values
// with `correction` (see adjust_p_values) and marks those selected at `alpha`. With
// `conditional`, each candidate is tested conditioning on all the other candidates. Throws
// ConfigError for alpha outside (0, 1], lags < 1 or an unknown correction.
std::vector<GrangerResult> granger_select(const std::vector<std::vector<double>>& y,
                                          const std::vector<NamedSeries>& candidates, int lags,
                                          double alpha, const std::string& correction,
                                          bool conditional = false);

}  // namespace cd
