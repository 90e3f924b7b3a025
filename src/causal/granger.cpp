#include "causal/granger.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <string>

#include <Eigen/Dense>
#include <boost/math/distributions/fisher_f.hpp>

#include "core/error.hpp"

namespace cd {

namespace {

using Series = std::vector<std::vector<double>>;  // one vector per episode

// Checks that `s` has the episode layout of `y` (same number of episodes, same lengths) and
// only finite values; `what` names it in the message.
void check_layout(const Series& y, const Series& s, const std::string& what) {
  if (s.size() != y.size())
    throw DataError("granger: " + what + " has " + std::to_string(s.size()) +
                    " episodes, the target has " + std::to_string(y.size()));
  for (size_t e = 0; e < s.size(); ++e) {
    if (s[e].size() != y[e].size())
      throw DataError("granger: episode " + std::to_string(e) + " of " + what + " has " +
                      std::to_string(s[e].size()) + " values, the target has " +
                      std::to_string(y[e].size()));
    for (double v : s[e])
      if (!std::isfinite(v))
        throw DataError("granger: " + what + " holds a non-finite value in episode " +
                        std::to_string(e));
  }
}

// Sum of squared residuals of the least-squares fit of b on the columns of A. Column-pivoting
// QR is rank-revealing and backward stable, so a collinear design (e.g. a constant candidate)
// still yields the minimal residual; SSR is taken from the explicit residual vector.
double ssr_of(const Eigen::Ref<const Eigen::MatrixXd>& A, const Eigen::VectorXd& b) {
  Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(A);
  Eigen::VectorXd beta = qr.solve(b);
  return (b - A * beta).squaredNorm();
}

// granger_f_test with the conditioning series by pointer (no copies in granger_select).
GrangerTest f_test(const Series& y, const Series& x, int lags,
                   const std::vector<const Series*>& conditioning) {
  if (lags < 1) throw DataError("granger: lags must be at least 1, got " + std::to_string(lags));
  check_layout(y, y, "the target");
  check_layout(y, x, "the candidate");
  for (size_t c = 0; c < conditioning.size(); ++c)
    check_layout(y, *conditioning[c], "conditioning variable " + std::to_string(c));

  const int L = lags;
  const int n_cond = static_cast<int>(conditioning.size());
  // Columns: [1, y lags, conditioning lags..., x lags]; the restricted model is the left block.
  const int k_r = 1 + L * (1 + n_cond);
  const int k_u = k_r + L;

  // Rows: every t with L earlier values inside the same episode (so nothing lags across a
  // boundary; an episode of at most L values contributes none).
  long n = 0;
  for (const auto& ep : y) n += std::max<long>(0, static_cast<long>(ep.size()) - L);
  const long df_den = n - k_u;
  if (df_den < 1)
    throw DataError("granger: too few rows for the test with " + std::to_string(L) +
                    " lags: " + std::to_string(n) + " usable rows (after dropping the first " +
                    std::to_string(L) + " of each episode), need more than " +
                    std::to_string(k_u));

  Eigen::MatrixXd X(n, k_u);
  Eigen::VectorXd target(n);
  long row = 0;
  for (size_t e = 0; e < y.size(); ++e) {
    const long len = static_cast<long>(y[e].size());
    for (long t = L; t < len; ++t, ++row) {
      target(row) = y[e][t];
      X(row, 0) = 1.0;
      for (int j = 1; j <= L; ++j) {
        X(row, j) = y[e][t - j];
        for (int c = 0; c < n_cond; ++c) X(row, 1 + L * (1 + c) + (j - 1)) = (*conditioning[c])[e][t - j];
        X(row, k_r + (j - 1)) = x[e][t - j];
      }
    }
  }

  const double ssr_r = ssr_of(X.leftCols(k_r), target);
  const double ssr_u = ssr_of(X, target);

  GrangerTest out;
  out.df_num = L;
  out.df_den = static_cast<int>(df_den);
  out.rows = n;
  // Round-off can make the nested fit's SSR a hair larger than the restricted one.
  const double gain = std::max(0.0, ssr_r - ssr_u);
  // A perfect unrestricted fit (SSR at round-off level: tiny against the target's variation, or
  // against its squared norm for a constant target) leaves F undefined or infinite.
  const double tss = (target.array() - target.mean()).square().sum();
  const double tiny = 1e-13 * tss + 1e-24 * target.squaredNorm();
  if (ssr_u <= tiny) {
    if (gain <= tiny) {
      out.f_stat = 0;
      out.p_value = 1;
    } else {
      out.f_stat = std::numeric_limits<double>::infinity();
      out.p_value = 0;
    }
    return out;
  }
  out.f_stat = (gain / L) / (ssr_u / static_cast<double>(df_den));
  boost::math::fisher_f_distribution<double> dist(L, static_cast<double>(df_den));
  out.p_value = boost::math::cdf(boost::math::complement(dist, out.f_stat));
  return out;
}

}  // namespace

GrangerTest granger_f_test(const Series& y, const Series& x, int lags,
                           const std::vector<Series>& conditioning) {
  std::vector<const Series*> cond;
  for (const Series& s : conditioning) cond.push_back(&s);
  return f_test(y, x, lags, cond);
}

std::vector<double> adjust_p_values(const std::vector<double>& p, const std::string& method) {
  if (method != "none" && method != "bonferroni" && method != "bh")
    throw ConfigError("unknown multiple-testing correction '" + method +
                      "' (available: none, bonferroni, bh)");
  for (double v : p)
    if (!(v >= 0 && v <= 1))  // also rejects NaN
      throw DataError("adjust_p_values: p-value " + std::to_string(v) + " is not in [0, 1]");
  const size_t m = p.size();
  std::vector<double> adj(p);
  if (method == "bonferroni") {
    for (double& v : adj) v = std::min(1.0, v * static_cast<double>(m));
  } else if (method == "bh") {
    // Step-up: with p sorted ascending, adj_(i) = min over j >= i of p_(j) * m / j, capped at 1
    // (computed as p / (j/m), the same arithmetic as statsmodels' fdr_bh).
    std::vector<size_t> order(m);
    std::iota(order.begin(), order.end(), 0);
    std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) { return p[a] < p[b]; });
    double running = 1.0;
    for (size_t r = m; r-- > 0;) {
      const double raw = p[order[r]] / (static_cast<double>(r + 1) / static_cast<double>(m));
      running = std::min(running, raw);
      adj[order[r]] = running;
    }
  }
  return adj;
}

std::vector<GrangerResult> granger_select(const Series& y, const std::vector<NamedSeries>& candidates,
                                          int lags, double alpha, const std::string& correction,
                                          bool conditional) {
  if (lags < 1) throw ConfigError("granger: --lags must be at least 1, got " + std::to_string(lags));
  if (!(alpha > 0 && alpha <= 1))
    throw ConfigError("granger: --alpha must be in (0, 1], got " + std::to_string(alpha));
  adjust_p_values({}, correction);  // validates the name before the (costlier) tests
  std::vector<GrangerResult> out;
  std::vector<double> p;
  for (size_t i = 0; i < candidates.size(); ++i) {
    std::vector<const Series*> others;
    if (conditional)
      for (size_t j = 0; j < candidates.size(); ++j)
        if (j != i) others.push_back(&candidates[j].episodes);
    GrangerResult r;
    r.variable = candidates[i].name;
    try {
      r.test = f_test(y, candidates[i].episodes, lags, others);
    } catch (const DataError& e) {
      throw DataError(std::string(e.what()) + " (candidate '" + r.variable + "')");
    }
    p.push_back(r.test.p_value);
    out.push_back(std::move(r));
  }
  std::vector<double> adj = adjust_p_values(p, correction);
  for (size_t i = 0; i < out.size(); ++i) {
    out[i].p_adjusted = adj[i];
    out[i].selected = adj[i] <= alpha;
  }
  return out;
}

}  // namespace cd
