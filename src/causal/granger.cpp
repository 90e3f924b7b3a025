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

// The lagged design of a test: columns [1, y lags, then L lags of each series of `blocks`],
// one row per t with L earlier values inside the same episode (so nothing lags across a
// boundary; an episode of at most L values contributes none). Checks the layouts and that the
// regression keeps at least one residual degree of freedom.
struct Design {
  Eigen::MatrixXd X;
  Eigen::VectorXd target;
  long rows = 0;
};

Design lagged_design(const Series& y, const std::vector<const Series*>& blocks, int L) {
  if (L < 1) throw DataError("granger: lags must be at least 1, got " + std::to_string(L));
  check_layout(y, y, "the target");
  for (size_t c = 0; c < blocks.size(); ++c)
    check_layout(y, *blocks[c], c + 1 == blocks.size() ? std::string("the candidate")
                                                       : "conditioning variable " + std::to_string(c));
  const int nb = static_cast<int>(blocks.size());
  const int k = 1 + L * (1 + nb);
  long n = 0;
  for (const auto& ep : y) n += std::max<long>(0, static_cast<long>(ep.size()) - L);
  if (n - k < 1)
    throw DataError("granger: too few rows for the test with " + std::to_string(L) +
                    " lags: " + std::to_string(n) + " usable rows (after dropping the first " +
                    std::to_string(L) + " of each episode), need more than " + std::to_string(k));
  Design d;
  d.rows = n;
  d.X.resize(n, k);
  d.target.resize(n);
  long row = 0;
  for (size_t e = 0; e < y.size(); ++e) {
    const long len = static_cast<long>(y[e].size());
    for (long t = L; t < len; ++t, ++row) {
      d.target(row) = y[e][t];
      d.X(row, 0) = 1.0;
      for (int j = 1; j <= L; ++j) {
        d.X(row, j) = y[e][t - j];
        for (int c = 0; c < nb; ++c) d.X(row, 1 + L * (1 + c) + (j - 1)) = (*blocks[c])[e][t - j];
      }
    }
  }
  return d;
}

// The test's figures from the two SSRs (df_den = rows - columns of the unrestricted model).
GrangerTest test_from_ssr(double ssr_r, double ssr_u, int L, long rows, long df_den,
                          const Eigen::VectorXd& target) {
  GrangerTest out;
  out.df_num = L;
  out.df_den = static_cast<int>(df_den);
  out.rows = rows;
  // Round-off can make the nested fit's SSR a hair larger than the restricted one.
  const double gain = std::max(0.0, ssr_r - ssr_u);
  out.partial_r2 = ssr_r > 0 ? gain / ssr_r : 0.0;
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

// granger_f_test with the conditioning series by pointer (no copies in granger_select).
GrangerTest f_test(const Series& y, const Series& x, int lags,
                   const std::vector<const Series*>& conditioning) {
  std::vector<const Series*> blocks = conditioning;
  blocks.push_back(&x);  // the candidate's lags are the last block
  const Design d = lagged_design(y, blocks, lags);
  const long k_u = d.X.cols(), k_r = k_u - lags;
  const double ssr_r = ssr_of(d.X.leftCols(k_r), d.target);
  const double ssr_u = ssr_of(d.X, d.target);
  return test_from_ssr(ssr_r, ssr_u, lags, d.rows, d.rows - k_u, d.target);
}

}  // namespace

GrangerTest granger_f_test(const Series& y, const Series& x, int lags,
                           const std::vector<Series>& conditioning) {
  std::vector<const Series*> cond;
  for (const Series& s : conditioning) cond.push_back(&s);
  return f_test(y, x, lags, cond);
}

std::vector<GrangerTest> conditional_f_tests(const Series& y, const std::vector<Series>& candidates,
                                             int lags) {
  const int m = static_cast<int>(candidates.size());
  std::vector<const Series*> blocks;
  for (const Series& c : candidates) blocks.push_back(&c);
  std::vector<GrangerTest> out;
  if (m == 0) return out;
  // Every candidate's block in one design: [1, y lags, candidate 0 lags, ..., candidate m-1].
  const Design d = lagged_design(y, blocks, lags);
  const long k = d.X.cols();
  Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(d.X);
  if (qr.rank() < k) {
    // Collinear candidates: no unique full-model coefficients, so one fit per candidate.
    for (int i = 0; i < m; ++i) {
      std::vector<const Series*> others;
      for (int j = 0; j < m; ++j)
        if (j != i) others.push_back(blocks[j]);
      out.push_back(f_test(y, candidates[i], lags, others));
    }
    return out;
  }
  const Eigen::VectorXd beta = qr.solve(d.target);
  const double ssr_u = (d.target - d.X * beta).squaredNorm();
  // (X'X)^-1 = P R^-1 R^-T P' from X P = Q R; dropping block B raises the SSR by
  // beta_B' [(X'X)^-1]_BB^-1 beta_B.
  const Eigen::MatrixXd R = qr.matrixR().topLeftCorner(k, k).triangularView<Eigen::Upper>();
  const Eigen::MatrixXd R_inv =
      R.triangularView<Eigen::Upper>().solve(Eigen::MatrixXd::Identity(k, k));
  const Eigen::MatrixXd V = qr.colsPermutation() * (R_inv * R_inv.transpose()) *
                            qr.colsPermutation().transpose();
  for (int i = 0; i < m; ++i) {
    const long at = 1 + static_cast<long>(lags) * (1 + i);
    const Eigen::VectorXd b = beta.segment(at, lags);
    const Eigen::MatrixXd v = V.block(at, at, lags, lags);
    const double gain = b.dot(v.ldlt().solve(b));
    out.push_back(test_from_ssr(ssr_u + std::max(0.0, gain), ssr_u, lags, d.rows, d.rows - k,
                                d.target));
  }
  return out;
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
  std::vector<GrangerTest> joint;
  if (conditional) {
    std::vector<Series> series;
    for (const NamedSeries& c : candidates) series.push_back(c.episodes);
    joint = conditional_f_tests(y, series, lags);
  }
  for (size_t i = 0; i < candidates.size(); ++i) {
    GrangerResult r;
    r.variable = candidates[i].name;
    try {
      r.test = conditional ? joint[i] : f_test(y, candidates[i].episodes, lags, {});
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
