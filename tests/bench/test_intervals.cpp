// Intervals and comparisons over training seeds (SPEC section 15): coverage on synthetic
// experiments with known rates, seed effects and shared task effects; P(A > B), the IQM and the
// power plan against hand computations; same seed, same bytes; the edge cases.
#include "bench/intervals.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <string>
#include <vector>

#include <boost/math/distributions/normal.hpp>

#include "core/error.hpp"
#include "core/rng.hpp"

namespace cd {
namespace {

double normal_cdf(double x) { return 0.5 * std::erfc(-x / std::sqrt(2.0)); }

// Synthetic evaluations (a probit model): an episode of seed s on task t succeeds with
// probability Phi(z + task_t + seed_s); task_t ~ N(0, task_sd^2) is drawn once per experiment
// and shared by both methods, seed_s ~ N(0, seed_sd^2) once per training seed. A probit sd of
// 0.3 is about a logit sd of 0.5, 0.6 about 1. The truth is intervals.hpp's: the expectation
// over the seed population on these tasks, in closed form as
// E Phi(a + seed) = Phi(a / sqrt(1 + seed_sd^2)).
struct Design {
  int seeds = 10, tasks = 25, trials = 4;
  double seed_sd = 0.3, task_sd = 0.6;
};

struct Method {
  SeedRuns runs;
  double truth = 0;
};

// The z whose rate over the task and seed populations is `rate`.
double base_z(double rate, const Design& d) {
  const double spread = std::sqrt(1 + d.seed_sd * d.seed_sd + d.task_sd * d.task_sd);
  return boost::math::quantile(boost::math::normal_distribution<double>(), rate) * spread;
}

Method draw_method(Rng& rng, double z, const std::vector<double>& task_offsets, const Design& d) {
  Method m;
  for (int s = 0; s < d.seeds; ++s) {
    const double seed_offset = d.seed_sd * standard_normal(rng);
    SeedOutcomes seed{{}, d.trials};
    for (double task : task_offsets) {
      const double p = normal_cdf(z + task + seed_offset);
      int successes = 0;
      for (int k = 0; k < d.trials; ++k) successes += rng.uniform() < p;
      seed.per_task.push_back(static_cast<double>(successes) / d.trials);
    }
    m.runs.push_back(seed);
  }
  for (double task : task_offsets)
    m.truth += normal_cdf((z + task) / std::sqrt(1 + d.seed_sd * d.seed_sd)) / d.tasks;
  return m;
}

// The Wilson interval of all episodes pooled, seeds ignored: what the rate interval replaces.
bool pooled_binomial_covers(const SeedRuns& runs, double truth) {
  double successes = 0, n = 0;
  for (const SeedOutcomes& seed : runs)
    for (double v : seed.per_task) {
      successes += v * seed.trials;
      n += seed.trials;
    }
  const double z = 1.959963984540054, p = successes / n, shrink = 1 + z * z / n;
  const double centre = (p + z * z / (2 * n)) / shrink;
  const double half = z * std::sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / shrink;
  return std::fabs(truth - centre) <= half;
}

struct Coverage {
  double rate = 0, difference = 0, pooled = 0;
};

// The share of `experiments` synthetic experiments (A at `rate`, B 0.1 nearer 0.5 on the same
// tasks) whose intervals hold the truth.
Coverage coverage(const Design& d, double rate, int experiments, uint64_t seed) {
  Rng rng(seed);
  const double z_a = base_z(rate, d), z_b = base_z(rate < 0.5 ? rate + 0.1 : rate - 0.1, d);
  int rate_hits = 0, difference_hits = 0, pooled_hits = 0;
  for (int e = 0; e < experiments; ++e) {
    std::vector<double> task_offsets(static_cast<size_t>(d.tasks));
    for (double& t : task_offsets) t = d.task_sd * standard_normal(rng);
    const Method a = draw_method(rng, z_a, task_offsets, d);
    const Method b = draw_method(rng, z_b, task_offsets, d);
    const Interval r = rate_interval(a.runs);
    rate_hits += r.lo <= a.truth && a.truth <= r.hi;
    const Comparison c = compare(a.runs, b.runs);
    difference_hits += c.lo <= a.truth - b.truth && a.truth - b.truth <= c.hi;
    pooled_hits += pooled_binomial_covers(a.runs, a.truth);
  }
  const double n = experiments;
  return {rate_hits / n, difference_hits / n, pooled_hits / n};
}

void record(const std::string& key, double value) {
  ::testing::Test::RecordProperty(key, std::to_string(value));
}

// Seeds from rows of per-task values, all with `trials` trials.
SeedRuns seeds_of(const std::vector<std::vector<double>>& rows, int trials = 1) {
  SeedRuns runs;
  for (const std::vector<double>& row : rows) runs.push_back({row, trials});
  return runs;
}

SeedRuns constant_seeds(int seeds, int tasks, double value) {
  return SeedRuns(static_cast<size_t>(seeds),
                  SeedOutcomes{std::vector<double>(static_cast<size_t>(tasks), value), 1});
}

bool same_bytes(double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0; }

// Coverage of the rate's and the difference's intervals for three true rates: at least 0.93,
// and at most `most` (1: no upper bound).
void expect_coverage(const Design& d, uint64_t stream, double most) {
  for (double rate : {0.2, 0.5, 0.85}) {
    SCOPED_TRACE("true rate " + std::to_string(rate));
    const Coverage c =
        coverage(d, rate, 4000, derive_seed(stream, static_cast<uint64_t>(rate * 100)));
    record("rate_" + std::to_string(rate), c.rate);
    record("difference_" + std::to_string(rate), c.difference);
    EXPECT_GE(c.rate, 0.93);
    EXPECT_LE(c.rate, most);
    EXPECT_GE(c.difference, 0.93);
    EXPECT_LE(c.difference, most);
  }
}

TEST(Intervals, CoverAtTheirNominalLevelAtTenSeedsTimesHundredEpisodes) {
  expect_coverage(Design{10, 25, 4}, 45, 0.97);  // 25 tasks x 4 trials per seed
}

TEST(Intervals, DoNotUndercoverAtThreeSeedsTimesTwentyFiveEpisodes) {
  expect_coverage(Design{3, 25, 1}, 46, 1.0);
}

// Also the boundary where every seed of a set can score the same, with a large seed spread.
TEST(Intervals, DoNotUndercoverNearZeroOrOne) {
  for (double rate : {0.05, 0.95}) {
    SCOPED_TRACE("true rate " + std::to_string(rate));
    const Coverage c = coverage({3, 25, 1, 0.6, 0.6}, rate, 4000, derive_seed(47, 1));
    record("rate_" + std::to_string(rate), c.rate);
    record("difference_" + std::to_string(rate), c.difference);
    EXPECT_GE(c.rate, 0.93);
    EXPECT_GE(c.difference, 0.93);
  }
}

// The same experiments as the ten-seed test: pooling the episodes ignores the seed variance.
TEST(Intervals, PooledBinomialIntervalUndercoversWhenSeedsVary) {
  const Coverage c = coverage({10, 25, 4}, 0.5, 4000, derive_seed(45, 50));
  record("pooled", c.pooled);
  EXPECT_LT(c.pooled, 0.80);
  EXPECT_GE(c.rate, 0.93);
}

TEST(Intervals, ProbabilityOfImprovementIsTheMeanOverTasksOfMannWhitney) {
  // Rows are seeds, columns tasks (2 trials, so values are k/2).
  const SeedRuns a = seeds_of({{1, 1, 0}, {0.5, 1, 0}, {0, 1, 0.5}}, 2);
  const SeedRuns b = seeds_of({{0.5, 1, 0.5}, {0.5, 0, 0.5}, {0, 0, 0.5}}, 2);
  // By hand, 9 (a, b) seed pairs per task, a win 1, a tie 1/2:
  //   task 0: A {1, .5, 0} vs B {.5, .5, 0}: 1 beats all (3); .5 ties two, beats 0 (2);
  //           0 ties one (.5): 5.5/9
  //   task 1: A {1, 1, 1} vs B {1, 0, 0}: each 1 ties one, beats two (2.5): 7.5/9
  //   task 2: A {0, 0, .5} vs B {.5, .5, .5}: only .5 ties three (1.5): 1.5/9
  //   P(A > B) = (5.5 + 7.5 + 1.5) / 27 = 14.5/27.
  // Difference: seed means A 2/3, 1.5/3, 1.5/3 (5/9), B 2/3, 1/3, 0.5/3 (3.5/9): 1/6.
  const Comparison c = compare(a, b);
  EXPECT_NEAR(c.p_improvement, 14.5 / 27, 1e-12);
  EXPECT_NEAR(c.difference, 1.0 / 6, 1e-12);
  EXPECT_NEAR(compare(b, a).p_improvement, 1 - 14.5 / 27, 1e-12);
  EXPECT_EQ(compare(a, a).p_improvement, 0.5);
}

TEST(Intervals, VerdictSaysWhichSideTheIntervalIsOn) {
  const SeedRuns good =
      seeds_of({{1, 1, 1, 1, 0}, {1, 1, 1, 1, 1}, {1, 1, 1, 0, 1}, {1, 1, 1, 1, 1}});
  const SeedRuns bad =
      seeds_of({{0, 0, 0, 0, 1}, {0, 0, 0, 0, 0}, {0, 1, 0, 0, 0}, {0, 0, 0, 0, 0}});
  const Comparison ab = compare(good, bad), ba = compare(bad, good), aa = compare(good, good);
  EXPECT_GT(ab.lo, 0);
  EXPECT_EQ(verdict_text(ab.verdict), "A better");
  EXPECT_EQ(verdict_text(ba.verdict), "B better");
  EXPECT_LT(ba.hi, 0);
  EXPECT_EQ(verdict_text(aa.verdict), "not resolved");
  EXPECT_EQ(aa.difference, 0);
  EXPECT_LT(aa.lo, 0);
  EXPECT_GT(aa.hi, 0);
  EXPECT_FALSE(ab.episode_only);
}

TEST(Intervals, OverConditionsIsTheMeanOfTheConditionsDifferences) {
  // Condition 0 as in the Mann-Whitney test (difference 1/6, P 14.5/27); condition 1: A and B
  // each 2 of 3 tasks on every seed except B's last seed (1 of 3): difference 1/9, P 4/6.
  const std::vector<SeedRuns> a = {
      seeds_of({{1, 1, 0}, {0.5, 1, 0}, {0, 1, 0.5}}, 2),
      seeds_of({{1, 1, 0}, {1, 0, 1}, {0, 1, 1}})};
  const std::vector<SeedRuns> b = {
      seeds_of({{0.5, 1, 0.5}, {0.5, 0, 0.5}, {0, 0, 0.5}}, 2),
      seeds_of({{1, 1, 0}, {1, 0, 1}, {0, 0, 1}})};
  // Condition 1 by task: task 0 A {1,1,0} B {1,1,0}: 4.5/9; task 1 A {1,0,1} B {1,0,0}:
  // 1s beat two and tie one (2.5 each), 0 ties two (1): 6/9; task 2 A {0,1,1} B {0,1,1}: 4.5/9.
  // Mean 15/27.
  const Comparison c = compare(a, b);
  EXPECT_NEAR(c.difference, (1.0 / 6 + 1.0 / 9) / 2, 1e-12);
  EXPECT_NEAR(c.p_improvement, (14.5 / 27 + 15.0 / 27) / 2, 1e-12);
  EXPECT_LT(c.lo, c.difference);
  EXPECT_GT(c.hi, c.difference);
  // A method needs the same seeds on every condition, and A and B the same conditions.
  std::vector<SeedRuns> short_b = b;
  short_b[1].pop_back();
  EXPECT_THROW(compare(a, short_b), DataError);
  EXPECT_THROW(compare(a, std::vector<SeedRuns>{b[0]}), DataError);
}

TEST(Intervals, InterquartileMeanDropsAQuarterAtEachEnd) {
  // 8 values, sorted 1 2 3 5 6 7 10 100: drop 2 at each end, mean of 3 5 6 7 = 5.25.
  EXPECT_DOUBLE_EQ(interquartile_mean({10, 1, 7, 2, 6, 3, 5, 100}), 5.25);
  // 10 values 0 1 2 4 ... 256: floor(10/4) = 2 at each end (not 2.5 rounded to 3), mean of
  // 2 4 8 16 32 64 = 21 (dropping 3: 15). scipy.stats.trim_mean(x, 0.25) gives 21 too.
  EXPECT_DOUBLE_EQ(interquartile_mean({256, 0, 128, 1, 64, 2, 32, 4, 16, 8}), 21.0);
  // 5 values drop 1 at each end; 3 values drop none (mean 4, not the median 2).
  EXPECT_DOUBLE_EQ(interquartile_mean({100, 1, 2, 3, 4}), 3.0);
  EXPECT_DOUBLE_EQ(interquartile_mean({9, 1, 2}), 4.0);
  EXPECT_THROW(interquartile_mean({}), DataError);
}

std::vector<std::vector<double>> synthetic_returns() {
  Rng rng(9);
  std::vector<std::vector<double>> returns(5);
  for (size_t s = 0; s < returns.size(); ++s)
    for (int e = 0; e < 20; ++e)
      returns[s].push_back(100 * static_cast<double>(s) + 50 * standard_normal(rng));
  return returns;
}

TEST(Intervals, IqmBootstrapIsSameSeedSameBytes) {
  const auto returns = synthetic_returns();
  const IqmInterval first = iqm_interval(returns, 7, 500), again = iqm_interval(returns, 7, 500);
  EXPECT_TRUE(same_bytes(first.lo, again.lo));
  EXPECT_TRUE(same_bytes(first.hi, again.hi));
  EXPECT_TRUE(same_bytes(first.iqm, again.iqm));
  const IqmInterval other = iqm_interval(returns, 8, 500);
  EXPECT_FALSE(same_bytes(first.lo, other.lo) && same_bytes(first.hi, other.hi));
  EXPECT_TRUE(same_bytes(first.iqm, other.iqm));  // the estimate itself is not random
  std::vector<double> all;
  for (const auto& r : returns) all.insert(all.end(), r.begin(), r.end());
  EXPECT_EQ(first.iqm, interquartile_mean(all));
  EXPECT_LT(first.lo, first.iqm);
  EXPECT_GT(first.hi, first.iqm);
  EXPECT_EQ(first.resamples, 500);
}

TEST(Intervals, IqmBootstrapResamplesSeedsAndEpisodes) {
  // Seeds differ, episodes within a seed do not: only drawing seeds moves the IQM.
  const IqmInterval between = iqm_interval({{0, 0, 0, 0}, {10, 10, 10, 10}, {20, 20, 20, 20},
                                            {30, 30, 30, 30}}, 3, 200);
  EXPECT_EQ(between.iqm, 15);
  EXPECT_LT(between.lo, 15);
  EXPECT_GT(between.hi, 15);
  // One seed: only drawing its episodes moves it.
  const IqmInterval within = iqm_interval({{0, 10, 20, 30, 40, 50, 60, 70}}, 3, 200);
  EXPECT_LT(within.lo, within.iqm);
  EXPECT_GT(within.hi, within.iqm);
  // Every return alike: every resample gives it.
  const IqmInterval flat = iqm_interval({{3, 3}, {3, 3, 3}}, 1, 50);
  EXPECT_EQ(flat.lo, 3);
  EXPECT_EQ(flat.hi, 3);
}

TEST(Intervals, IqmIntervalRefusesWhatItCannotUse) {
  EXPECT_THROW(iqm_interval({}, 1), DataError);
  EXPECT_THROW(iqm_interval({{1.0}, {}}, 1), DataError);
  EXPECT_THROW(iqm_interval({{1.0}}, 1, 0), ConfigError);
}

// compare_iqm: A's IQM less B's. Against a B whose every return is c, each resample's B IQM is c
// and A's draws are iqm_interval's (A is drawn first from the same generator): the interval is
// A's own shifted by c.
TEST(Intervals, IqmComparisonAgainstAConstantIsTheShiftedIqmInterval) {
  const auto a = synthetic_returns();
  const IqmInterval alone = iqm_interval(a, 11, 400);
  const IqmComparison c = compare_iqm(a, {{50.0, 50.0, 50.0}}, 11, 400);
  std::vector<double> all;
  for (const auto& r : a) all.insert(all.end(), r.begin(), r.end());
  EXPECT_EQ(c.a, interquartile_mean(all));
  EXPECT_EQ(c.b, 50.0);
  EXPECT_DOUBLE_EQ(c.difference, c.a - 50.0);
  EXPECT_NEAR(c.lo, alone.lo - 50.0, 1e-9);
  EXPECT_NEAR(c.hi, alone.hi - 50.0, 1e-9);
  EXPECT_EQ(c.resamples, 400);
  // Same seed, same bytes; another seed, another interval around the same estimate.
  const IqmComparison again = compare_iqm(a, {{50.0, 50.0, 50.0}}, 11, 400);
  EXPECT_TRUE(same_bytes(c.lo, again.lo) && same_bytes(c.hi, again.hi));
  const IqmComparison other = compare_iqm(a, {{50.0, 50.0, 50.0}}, 12, 400);
  EXPECT_FALSE(same_bytes(c.lo, other.lo) && same_bytes(c.hi, other.hi));
  EXPECT_TRUE(same_bytes(c.difference, other.difference));
}

TEST(Intervals, IqmComparisonVerdictAndProbabilityOfImprovement) {
  // Flat returns: every resample gives 3 - 1; every A seed beats every B seed.
  const IqmComparison flat = compare_iqm({{3, 3}, {3, 3, 3}}, {{1, 1}}, 1, 50);
  EXPECT_EQ(flat.difference, 2);
  EXPECT_EQ(flat.lo, 2);
  EXPECT_EQ(flat.hi, 2);
  EXPECT_EQ(flat.verdict, Verdict::a_better);
  EXPECT_EQ(flat.p_improvement, 1.0);
  EXPECT_EQ(compare_iqm({{1, 1}}, {{3, 3}, {3, 3, 3}}, 1, 50).verdict, Verdict::b_better);
  // A method against itself: a difference of 0 inside its interval, seed pairs tie on average.
  const auto a = synthetic_returns();
  const IqmComparison self = compare_iqm(a, a, 5, 400);
  EXPECT_EQ(self.difference, 0);
  EXPECT_LT(self.lo, 0);
  EXPECT_GT(self.hi, 0);
  EXPECT_EQ(self.verdict, Verdict::not_resolved);
  EXPECT_DOUBLE_EQ(self.p_improvement, 0.5);
  // Seeds 100 apart (synthetic_returns): A's seeds s + 3 against B's seeds s: P(A > B) by hand.
  // A = seeds {3, 4}, B = seeds {0, 1, 2}: every pair has A's seed higher.
  const IqmComparison ahead = compare_iqm({a[3], a[4]}, {a[0], a[1], a[2]}, 5, 400);
  EXPECT_EQ(ahead.p_improvement, 1.0);
  EXPECT_GT(ahead.difference, 0);
  EXPECT_THROW(compare_iqm({}, a, 1), DataError);
  EXPECT_THROW(compare_iqm(a, {{1.0}, {}}, 1), DataError);
  EXPECT_THROW(compare_iqm(a, a, 1, 0), ConfigError);
}

TEST(Intervals, VarianceComponentsSplitSeedFromEpisodeNoise) {
  // Seed means 3/4 and 1/4 of 4 episodes: episode variance p(1-p) n/(n-1) = 3/16 * 4/3 = 1/4
  // for both; s^2 of the seed means = 2 * (1/4)^2 = 1/8, less 1/4 / 4: seed variance 1/16.
  const VarianceComponents c = variance_components(seeds_of({{1, 0, 1, 1}, {0, 0, 1, 0}}));
  EXPECT_NEAR(c.episode_variance, 0.25, 1e-12);
  EXPECT_NEAR(c.seed_variance, 0.0625, 1e-12);
  EXPECT_EQ(c.seeds, 2);
  EXPECT_EQ(c.episodes_per_seed, 4);
}

TEST(Intervals, PowerFollowsTheTwoLevelVariance) {
  // sigma_seed^2 = 0.01 (10 points), sigma_episode^2 = 0.25, 5 seeds x 25 episodes:
  //   one seed's mean 0.01 + 0.25/25 = 0.02, a method's mean 0.02/5 = 0.004;
  //   rate half-width t(4) sqrt(0.004) = 2.7764451 * 0.0632456 = 0.1755965;
  //   difference half-width t(8) sqrt(0.008) = 2.3060041 * 0.0894427 = 0.2062555;
  //   10 points: S = 2 (1.9599640 + 0.8416212)^2 * 0.02 / 0.01 = 31.40 -> 32 seeds;
  //   4x the tasks: 0.01 + 0.25/100 = 0.0125: 19.62 -> 20 seeds.
  const PowerPlan p = power({0.01, 0.25, 5, 25});
  EXPECT_NEAR(p.rate_half_width, 2.7764451051977987 * std::sqrt(0.004), 1e-9);
  EXPECT_NEAR(p.difference_half_width, 2.3060041350333704 * std::sqrt(0.008), 1e-9);
  EXPECT_EQ(p.seeds_needed, 32);
  EXPECT_EQ(p.seeds_needed_4x_tasks, 20);
  EXPECT_EQ(power({0.01, 0.25, 5, 25}, 0.2).seeds_needed, 8);  // 31.40 / 4 = 7.85
  EXPECT_THROW(power({0.01, 0.25, 0, 25}), DataError);
}

TEST(Intervals, AllSeedsAtFullSuccessGiveAnIntervalBelowOne) {
  // 3 seeds x 25 episodes, all successes. Floor: p = 77/79, F = p(1-p)/75 = 3.2901e-4, times
  // chi2(2) lower quartile / 2 = -ln 0.75 = 0.28768: V = 9.4649e-5. Wilson at n = m(1-m)/V with
  // m taken 1/150 from 1: n = 69.966; lo = n / (n + t(2)^2) = 69.966 / (69.966 + 18.513).
  const Interval r = rate_interval(constant_seeds(3, 25, 1.0));
  EXPECT_EQ(r.mean, 1.0);
  EXPECT_EQ(r.hi, 1.0);
  EXPECT_NEAR(r.lo, 0.7907650, 1e-6);
  EXPECT_EQ(r.seeds, 3);
  EXPECT_EQ(r.episodes, 75);
  // And the mirror image at 0.
  const Interval zero = rate_interval(constant_seeds(3, 25, 0.0));
  EXPECT_EQ(zero.lo, 0.0);
  EXPECT_NEAR(zero.hi, 1 - 0.7907650, 1e-6);
}

TEST(Intervals, OneSeedGivesTheEpisodeLevelAlone) {
  // 20 of 25: V = F = p(1-p)/25 at p = 22/29; n = 0.16/V = 21.844; Wilson with z 1.96.
  SeedOutcomes seed{std::vector<double>(25, 0.0), 1};
  for (int t = 0; t < 20; ++t) seed.per_task[static_cast<size_t>(t)] = 1;
  const Interval r = rate_interval({seed});
  EXPECT_TRUE(r.episode_only);
  EXPECT_NEAR(r.lo, 0.5940673, 1e-6);
  EXPECT_NEAR(r.hi, 0.9161986, 1e-6);
  EXPECT_TRUE(compare({seed}, constant_seeds(3, 25, 0.5)).episode_only);
  EXPECT_FALSE(rate_interval({seed, seed}).episode_only);
}

TEST(Intervals, UnusableInputThrowsDataError) {
  EXPECT_THROW(rate_interval({}), DataError);
  EXPECT_THROW(rate_interval(seeds_of({{}})), DataError);
  EXPECT_THROW(rate_interval(seeds_of({{1, 0}, {1}})), DataError);
  EXPECT_THROW(rate_interval(seeds_of({{1.5}})), DataError);
  EXPECT_THROW(rate_interval(seeds_of({{1}}, 0)), DataError);
  EXPECT_THROW(compare(seeds_of({{1, 0}}), seeds_of({{1}})), DataError);
  EXPECT_THROW(variance_components({}), DataError);
}

}  // namespace
}  // namespace cd
