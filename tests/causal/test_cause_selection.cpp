// Granger cause selection on synthetic latents (causal/cause_selection): a lagged driver is
// found, noise is not, the corrections and the cap act, and the three rules on a weak,
// autocorrelated decoy.
#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "app/settings.hpp"
#include "causal/cause_selection.hpp"
#include "causal/granger.hpp"
#include "core/error.hpp"
#include "core/rng.hpp"

namespace cd {
namespace {

using Series = std::vector<std::vector<double>>;

double gauss(Rng& r) {  // Box-Muller, fixed by this code
  double u = std::max(r.uniform(), 1e-300), v = r.uniform();
  return std::sqrt(-2 * std::log(u)) * std::cos(2 * M_PI * v);
}

// An AR(1) series per episode.
Series ar_series(Rng& r, int episodes, int len) {
  Series s(episodes);
  for (auto& ep : s) {
    double x = 0;
    for (int t = 0; t < len; ++t) ep.push_back(x = 0.7 * x + gauss(r));
  }
  return s;
}

// An AR(1) series per episode with coefficient rho.
Series ar_series(Rng& r, int episodes, int len, double rho, double scale = 1.0) {
  Series s(episodes);
  for (auto& ep : s) {
    double x = 0;
    for (int t = 0; t < len; ++t) ep.push_back(x = rho * x + scale * gauss(r));
  }
  return s;
}

// speed_t = sum_i coupling[i] * driver_i(t-2) + noise.
Series speed_from(const std::vector<Series>& drivers, const std::vector<double>& coupling, Rng& r) {
  Series y(drivers[0].size());
  for (size_t e = 0; e < y.size(); ++e)
    for (size_t t = 0; t < drivers[0][e].size(); ++t) {
      double v = gauss(r);
      for (size_t i = 0; i < drivers.size(); ++i)
        if (t >= 2) v += coupling[i] * drivers[i][e][t - 2];
      y[e].push_back(v);
    }
  return y;
}

CimSettings settings(const std::string& correction, double alpha = 0.01, int max_causes = 0) {
  CimSettings c;
  c.selection = "bivariate";
  c.lags = 3;
  c.alpha = alpha;
  c.correction = correction;
  c.max_causes = max_causes;
  return c;
}

TEST(CimSelection, LaggedDriverIsSelectedNoiseIsNot) {
  Rng r(7);
  std::vector<Series> latents;
  for (int i = 0; i < 8; ++i) latents.push_back(ar_series(r, 3, 200));
  Series y = speed_from({latents[5]}, {1.0}, r);
  CauseSelection sel = select_causes(y, latents, settings("bonferroni"), false);
  EXPECT_EQ(sel.selected, std::vector<int>{5});
  EXPECT_EQ(sel.ranked, std::vector<int>{5});
  EXPECT_FALSE(sel.fallback);
  EXPECT_EQ(sel.rows, 3 * (200 - 3));
  ASSERT_EQ(sel.tests.size(), 8u);
  EXPECT_TRUE(sel.tests[5].selected);
  EXPECT_LT(sel.tests[5].test.p_value, 1e-10);
  EXPECT_DOUBLE_EQ(sel.threshold_p, 0.01 / 8);
  for (int i = 0; i < 8; ++i) {
    EXPECT_NEAR(sel.tests[i].p_adjusted, std::min(1.0, 8 * sel.tests[i].test.p_value), 1e-12);
    // The tests are the library's bivariate F tests.
    GrangerTest g = granger_f_test(y, latents[i], 3);
    EXPECT_EQ(sel.tests[i].test.p_value, g.p_value);
    EXPECT_EQ(sel.tests[i].test.df_den, 3 * 197 - 7);
  }
  // cim-mlp: every latent is an input, the tests and picks are still recorded.
  CauseSelection all = select_causes(y, latents, settings("bonferroni"), true);
  EXPECT_EQ(all.selected.size(), 8u);
  EXPECT_EQ(all.ranked, std::vector<int>{5});
  EXPECT_TRUE(all.tests[0].selected);
  EXPECT_FALSE(all.tests[0].significant);
}

TEST(CimSelection, BonferroniDropsABorderlineCauseThatNoneKeeps) {
  // A weak driver whose raw p lies in (alpha/m, alpha]: found without correction only. The
  // data are fixed by the seed; the coupling is searched once for such a p.
  const int m = 10;
  for (double c = 0.02; c < 0.5; c += 0.005) {
    Rng r(11);
    std::vector<Series> latents;
    for (int i = 0; i < m; ++i) latents.push_back(ar_series(r, 2, 300));
    Series y = speed_from({latents[2]}, {c}, r);
    const double p = granger_f_test(y, latents[2], 3).p_value;
    if (!(p > 0.01 / m && p <= 0.01)) continue;
    // Keep noise latents out of the picture when they pass by chance at 0.01.
    bool clean = true;
    for (int i = 0; i < m; ++i)
      if (i != 2 && granger_f_test(y, latents[i], 3).p_value <= 0.01) clean = false;
    if (!clean) continue;
    CauseSelection none = select_causes(y, latents, settings("none"), false);
    CauseSelection bonf = select_causes(y, latents, settings("bonferroni"), false);
    EXPECT_EQ(none.selected, std::vector<int>{2});
    EXPECT_FALSE(none.fallback);
    EXPECT_TRUE(bonf.fallback);  // nothing significant: the smallest-p latent, flagged
    EXPECT_EQ(bonf.significant, 0);
    EXPECT_EQ(bonf.selected, std::vector<int>{2});
    return;
  }
  FAIL() << "no coupling gave a borderline p-value";
}

TEST(CimSelection, MaxCausesKeepsTheStrongestAndBhIsBetweenTheOthers) {
  Rng r(5);
  std::vector<Series> latents;
  for (int i = 0; i < 6; ++i) latents.push_back(ar_series(r, 2, 400));
  // Drivers 1, 3, 4 with falling strength.
  Series y = speed_from({latents[1], latents[3], latents[4]}, {2.0, 1.0, 0.5}, r);
  CauseSelection uncapped = select_causes(y, latents, settings("bonferroni", 0.01, 0), false);
  EXPECT_EQ(uncapped.selected, (std::vector<int>{1, 3, 4}));
  EXPECT_FALSE(uncapped.capped);
  CauseSelection capped = select_causes(y, latents, settings("bonferroni", 0.01, 2), false);
  EXPECT_EQ(capped.selected, (std::vector<int>{1, 3}));
  EXPECT_TRUE(capped.capped);
  EXPECT_EQ(capped.significant, 3);
  EXPECT_TRUE(capped.tests[4].significant);
  EXPECT_FALSE(capped.tests[4].selected);
  CauseSelection one = select_causes(y, latents, settings("bonferroni", 0.01, 1), false);
  EXPECT_EQ(one.selected, std::vector<int>{1});
  // BH's raw-p threshold lies between Bonferroni's and no correction's.
  CauseSelection bh = select_causes(y, latents, settings("bh"), false);
  EXPECT_EQ(bh.selected, (std::vector<int>{1, 3, 4}));
  EXPECT_GE(bh.threshold_p, 0.01 / 6);
  EXPECT_LE(bh.threshold_p, 0.01);
  EXPECT_DOUBLE_EQ(bh.threshold_p, 3 * 0.01 / 6);
}

TEST(CimSelection, NothingSignificantFallsBackToTheSmallestP) {
  Rng r(9);
  std::vector<Series> latents;
  for (int i = 0; i < 5; ++i) latents.push_back(ar_series(r, 2, 100));
  Series y = ar_series(r, 2, 100);
  CauseSelection sel = select_causes(y, latents, settings("bonferroni", 1e-12), false);
  ASSERT_TRUE(sel.fallback);
  ASSERT_EQ(sel.selected.size(), 1u);
  for (const auto& t : sel.tests) EXPECT_GE(t.test.p_value, sel.tests[sel.selected[0]].test.p_value);
  EXPECT_THROW(select_causes(y, latents, settings("holm"), false), ConfigError);
}

TEST(CimSelection, OnlyEligibleLatentsArePickedAllAreTested) {
  // Two drivers (1 strong, 5 weaker) among 8 latents: with 1 ineligible, 5 is picked alone;
  // the tests of every latent are still run and recorded; the fallback too stays eligible.
  Rng r(7);
  std::vector<Series> latents;
  for (int i = 0; i < 8; ++i) latents.push_back(ar_series(r, 3, 200));
  Series y = speed_from({latents[1], latents[5]}, {2.0, 1.0}, r);
  CauseSelection both = select_causes(y, latents, settings("bonferroni"), false);
  EXPECT_EQ(both.selected, (std::vector<int>{1, 5}));
  std::vector<bool> eligible(8, true);
  eligible[1] = false;
  CauseSelection sel = select_causes(y, latents, settings("bonferroni"), false, eligible);
  EXPECT_EQ(sel.selected, std::vector<int>{5});
  EXPECT_EQ(sel.significant, 1);
  EXPECT_FALSE(sel.tests[1].significant);
  EXPECT_EQ(sel.tests[1].test.p_value, both.tests[1].test.p_value);
  // Nothing passes among the eligible: the fallback is the best eligible one, never latent 1.
  std::vector<bool> only_noise(8, true);
  only_noise[1] = only_noise[5] = false;
  CauseSelection fb = select_causes(y, latents, settings("bonferroni", 1e-300), false, only_noise);
  ASSERT_TRUE(fb.fallback);
  ASSERT_EQ(fb.ranked.size(), 1u);
  EXPECT_NE(fb.ranked[0], 1);
  EXPECT_NE(fb.ranked[0], 5);
  EXPECT_THROW(select_causes(y, latents, settings("bonferroni"), false, std::vector<bool>(8, false)),
               DataError);
  EXPECT_THROW(select_causes(y, latents, settings("bonferroni"), false, std::vector<bool>(3, true)),
               Error);
}

// The situation of the driving data: 20k autocorrelated rows, a real driver, and a decoy that
// carries a trace of the driver under a slow AR(0.99) wander of its own. The decoy's lags do
// predict the speed a little (a p-value test at this row count calls that significant), but
// they explain well under 1% of the variance the speed's own lags leave, and nothing given the
// driver's lags.
TEST(CimSelection, WeakAutocorrelatedDecoyPassesTheBivariateTestOnlyNotTheDefault) {
  Rng r(3);
  const int E = 20, T = 1000;
  Series driver = ar_series(r, E, T, 0.7);
  Series wander = ar_series(r, E, T, 0.99);
  Series decoy = wander;
  for (int e = 0; e < E; ++e)
    for (int t = 0; t < T; ++t) decoy[e][t] += 0.06 * driver[e][t];
  Series err = ar_series(r, E, T, 0.98, 0.3);  // persistent error the speed's lags half absorb
  Series y(E);
  for (int e = 0; e < E; ++e)
    for (int t = 0; t < T; ++t)
      y[e].push_back((t > 0 ? 0.5 * y[e][t - 1] : 0.0) + (t >= 2 ? 0.6 * driver[e][t - 2] : 0.0) +
                     err[e][t] + 0.3 * gauss(r));
  std::vector<Series> latents = {ar_series(r, E, T, 0.99), driver, ar_series(r, E, T, 0.99),
                                 decoy, ar_series(r, E, T, 0.7)};
  const int kDriver = 1, kDecoy = 3;

  // The data are what the test claims: the decoy's bivariate p is tiny, its share is small.
  const GrangerTest d = granger_f_test(y, latents[kDecoy], 3);
  ASSERT_LT(d.p_value, 1e-6);
  ASSERT_LT(d.partial_r2, 0.005);
  ASSERT_GT(granger_f_test(y, latents[kDriver], 3).partial_r2, 0.3);

  // The default rule (partial R^2 >= 0.01) keeps the driver alone.
  CimSettings def;
  def.max_causes = 0;
  ASSERT_EQ(def.selection, "partial_r2");
  CauseSelection share = select_causes(y, latents, def, false);
  EXPECT_EQ(share.selected, std::vector<int>{kDriver});
  EXPECT_FALSE(share.tests[kDecoy].significant);
  EXPECT_EQ(share.rule, "partial_r2");
  EXPECT_DOUBLE_EQ(share.tests[kDecoy].test.partial_r2, d.partial_r2);

  // The bivariate test with Bonferroni picks the decoy too.
  CauseSelection bivariate = select_causes(y, latents, settings("bonferroni"), false);
  EXPECT_EQ(bivariate.selected, (std::vector<int>{kDriver, kDecoy}));

  // Given the driver's lags, the decoy adds nothing: the conditional test drops it.
  CimSettings cond = settings("bonferroni");
  cond.selection = "conditional";
  CauseSelection conditional = select_causes(y, latents, cond, false);
  EXPECT_EQ(conditional.selected, std::vector<int>{kDriver});
  EXPECT_GT(conditional.tests[kDecoy].p_adjusted, 0.01);
  // Each conditional test is the one granger_f_test gives with the others as conditioning.
  std::vector<Series> others = {latents[0], latents[1], latents[2], latents[4]};
  const GrangerTest direct = granger_f_test(y, latents[kDecoy], 3, others);
  EXPECT_NEAR(conditional.tests[kDecoy].test.f_stat, direct.f_stat, 1e-8 * direct.f_stat);
  EXPECT_EQ(conditional.tests[kDecoy].test.df_den, direct.df_den);

  CimSettings bad = def;
  bad.selection = "lasso";
  EXPECT_THROW(select_causes(y, latents, bad, false), ConfigError);
}

TEST(CimSelection, PartialR2RanksByShareAndFallsBackToTheLargest) {
  Rng r(5);
  std::vector<Series> latents;
  for (int i = 0; i < 6; ++i) latents.push_back(ar_series(r, 2, 400));
  Series y = speed_from({latents[1], latents[3], latents[4]}, {2.0, 1.0, 0.5}, r);
  CimSettings c;
  c.max_causes = 2;
  CauseSelection sel = select_causes(y, latents, c, false);
  std::vector<double> share;
  for (const auto& t : sel.tests) share.push_back(t.test.partial_r2);
  EXPECT_GT(share[1], share[3]);
  EXPECT_GT(share[3], share[4]);
  EXPECT_EQ(sel.selected, (std::vector<int>{1, 3}));
  EXPECT_TRUE(sel.capped);
  // partial R^2 = (SSR_r - SSR_u) / SSR_r = F L / (F L + df_den).
  for (const auto& t : sel.tests) {
    const double f = t.test.f_stat * 3;
    EXPECT_NEAR(t.test.partial_r2, f / (f + t.test.df_den), 1e-12);
  }
  c.min_partial_r2 = 0.99;  // nothing reaches it: the largest share alone, flagged
  CauseSelection none = select_causes(y, latents, c, false);
  EXPECT_TRUE(none.fallback);
  EXPECT_EQ(none.selected, std::vector<int>{1});
}

TEST(GrangerConditional, OneJointFitEqualsOneFitPerCandidate) {
  Rng r(21);
  std::vector<Series> xs;
  for (int i = 0; i < 5; ++i) xs.push_back(ar_series(r, 3, 150));
  Series y = speed_from({xs[0], xs[2]}, {1.0, 0.3}, r);
  auto per_candidate = [&](const std::vector<Series>& c, size_t i) {
    std::vector<Series> others;
    for (size_t j = 0; j < c.size(); ++j)
      if (j != i) others.push_back(c[j]);
    return granger_f_test(y, c[i], 2, others);
  };
  std::vector<GrangerTest> joint = conditional_f_tests(y, xs, 2);
  ASSERT_EQ(joint.size(), xs.size());
  for (size_t i = 0; i < xs.size(); ++i) {
    const GrangerTest want = per_candidate(xs, i);
    EXPECT_NEAR(joint[i].f_stat, want.f_stat, 1e-8 * std::max(1.0, want.f_stat)) << i;
    EXPECT_NEAR(joint[i].p_value, want.p_value, 1e-8) << i;
    EXPECT_NEAR(joint[i].partial_r2, want.partial_r2, 1e-10) << i;
    EXPECT_EQ(joint[i].df_den, want.df_den);
    EXPECT_EQ(joint[i].rows, want.rows);
  }
  // A duplicated candidate makes the design rank-deficient: one fit per candidate, same answer.
  std::vector<Series> dup = xs;
  dup.push_back(xs[1]);
  std::vector<GrangerTest> fallback = conditional_f_tests(y, dup, 2);
  for (size_t i = 0; i < dup.size(); ++i)
    EXPECT_NEAR(fallback[i].f_stat, per_candidate(dup, i).f_stat, 1e-8 * std::max(1.0, fallback[i].f_stat));
}

}  // namespace
}  // namespace cd
