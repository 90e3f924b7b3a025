#pragma once
// Intervals and comparisons over training seeds (SPEC section 15, issue 45): pure functions of
// per-seed, per-task outcomes, so their coverage can be checked on synthetic experiments.
//
// What the truth is: the suite's tasks are fixed (a suite is a fixed list of routes and every
// seed runs all of them), so a rate's truth is its expectation over the population of training
// seeds (and their episodes) on THESE tasks. Seeds are the independent replicates; a seed's mean
// over tasks already carries its episodes' noise, so the spread of seed means holds both levels
// of variance, and task effects, the same for every seed and for both methods, add none.
// Generalising to other tasks of the same kind is not claimed.
#include <cstdint>
#include <string>
#include <vector>

namespace cd {

// One training seed on one condition (suite): per task, the mean over its `trials` trials of a
// 0/1 outcome (success, collision, ...), so each value is in [0,1]. Every seed of a method has
// the same tasks in the same order.
struct SeedOutcomes {
  std::vector<double> per_task;
  int trials = 1;
};
// One method on one condition: one entry per training seed.
using SeedRuns = std::vector<SeedOutcomes>;

// A rate with its 95% interval (lo and hi clamped to [0,1]).
struct Interval {
  double mean = 0, lo = 0, hi = 0;
  int seeds = 0;
  long episodes = 0;
  // One seed: no between-seed variance can be seen, and the interval holds the episode
  // (binomial) level alone; it is too narrow for the seed population.
  bool episode_only = false;
};

// The mean rate m (mean over seeds of each seed's mean over tasks) with a 95% interval. The
// variance of m is V = max(s^2/S, c F): s^2, the sample variance of the seed means, holds both
// levels (seeds, then their episodes); F, the binomial variance m cannot be below,
// p(1-p)/S^2 * sum_s 1/n_s at the pooled rate shrunk as Agresti-Coull, p = (x + 2)/(n + 4),
// keeps seeds that agree by chance (3 seeds all 25 of 25) from giving a zero-width or too
// narrow interval; c = chi2(S-1) lower quartile/(S-1) lets s^2 below F count down to what
// episode noise alone reaches 1 time in 4. The interval is Wilson's score interval at the
// effective number of episodes n = m(1-m)/V with t(S-1) for z: m +- t sqrt(V) in the middle,
// asymmetric near 0 and 1 where seed means are skewed, hi = 1 when every episode succeeded.
// Synthetic coverage (probit seed sd 0.3, task sd 0.6, rates 0.05-0.95): 94.8-95.3% at 10 seeds
// x 100 episodes, 98-99.5% at 3 x 25 (t(2) is wide); without seed effects 96-98% (the floor);
// at rates near 0 or 1 with large seed spreads it falls at 10 seeds: 91-93% at probit sd 0.6,
// 85-90% at sd 1 (seeds from 0 to 40% at a rate of 0.05), where only more seeds help.
// One seed: F alone with the normal quantile (episode_only). Throws DataError on no seeds, no
// tasks, seeds with different task counts, trials < 1 or values outside [0,1].
Interval rate_interval(const SeedRuns& runs);

enum class Verdict { a_better, b_better, not_resolved };
// "A better", "B better", "not resolved".
std::string verdict_text(Verdict verdict);

// A - B on the same tasks (rate units), truth as above for each. The pairing by task is in the
// means: every seed of A and of B is averaged over the same tasks, so the task effects they
// share are the same in every seed mean and cancel in A - B without adding variance. A's and
// B's seeds are independent trainings: the variance is V_A + V_B (each V as in rate_interval),
// the quantile Student t at the Welch-Satterthwaite df; lo and hi clamped to [-1,1]. Synthetic
// coverage (as above, B 10 points nearer 0.5): 94.6-95.4% at 10 x 100, 96.7-96.8% at 3 x 25.
struct Comparison {
  double difference = 0, lo = 0, hi = 0;
  // rliable's probability of improvement: per task, the Mann-Whitney statistic of A's seeds
  // against B's (the share of (a, b) seed pairs with a > b, ties counting 1/2), averaged over
  // tasks (over conditions: over each condition's tasks, then over conditions).
  double p_improvement = 0.5;
  Verdict verdict = Verdict::not_resolved;  // at 95%: the interval above or below 0
  bool episode_only = false;                // a side had one seed (see Interval)
};
Comparison compare(const SeedRuns& a, const SeedRuns& b);

// Over conditions: the mean over conditions of the difference. Each method has the same seeds
// on every condition (index s is one training run), so a seed's value is its mean over
// conditions and the interval is built from those values as above. Throws DataError when the
// condition counts, a method's seed counts across conditions or A's and B's tasks differ.
Comparison compare(const std::vector<SeedRuns>& a_by_condition,
                   const std::vector<SeedRuns>& b_by_condition);

// Interquartile mean as rliable computes it (scipy.stats.trim_mean(x, 0.25)): sort the n
// values, drop floor(n/4) at each end, the plain mean of the rest (no fractional weights: 5
// values drop 1 at each end, 3 values drop none). Throws DataError on no values.
double interquartile_mean(std::vector<double> values);

struct IqmInterval {
  double iqm = 0, lo = 0, hi = 0;
  int resamples = 0;
};
// IQM of returns over seeds x episodes (MuJoCo-Image) with a 95% percentile bootstrap interval.
// Each resample draws S seeds with replacement, then each drawn seed's episodes with
// replacement (a two-level bootstrap: both variance levels), and takes the IQM of all drawn
// values; lo and hi are the 2.5% and 97.5% quantiles (linear interpolation) of the resampled
// IQMs. Resample b uses Rng(derive_seed(seed, b)): same input and seed, same bytes. With few
// seeds the interval is narrow (3 seeds give 10 distinct seed draws). Throws DataError on no
// seeds or a seed without episodes, ConfigError on resamples < 1.
IqmInterval iqm_interval(const std::vector<std::vector<double>>& returns_by_seed, uint64_t seed,
                         int resamples = 10000);

// A's IQM return less B's (MuJoCo-Image, one environment; more is better), with a 95%
// percentile interval: each resample draws A's and B's two-level bootstraps (as iqm_interval)
// from one Rng(derive_seed(seed, b)), A first; A's and B's seeds are independent trainings, so
// they are drawn independently. The verdict: the interval above 0 (a_better) or below (b_better).
// p_improvement: the share of (A seed, B seed) pairs whose seed IQM is higher for A, ties 1/2.
// Throws as iqm_interval.
struct IqmComparison {
  double a = 0, b = 0, difference = 0, lo = 0, hi = 0, p_improvement = 0.5;
  Verdict verdict = Verdict::not_resolved;
  int resamples = 0;
};
IqmComparison compare_iqm(const std::vector<std::vector<double>>& a_by_seed,
                          const std::vector<std::vector<double>>& b_by_seed, uint64_t seed,
                          int resamples = 10000);

// The variance components of one method on one condition. episode_variance: the variance of one
// 0/1 episode within a seed (mean over seeds of p_s(1-p_s) n_s/(n_s-1), pooled over the seed's
// tasks, so differences between tasks count as episode noise and the plan errs on the safe
// side); seed_variance: the variance of the seeds' true rates, s^2 of the seed means less
// episode_variance/n, at least 0 (0 with one seed). episodes_per_seed: n, the mean over seeds.
struct VarianceComponents {
  double seed_variance = 0, episode_variance = 0;
  int seeds = 0;
  double episodes_per_seed = 0;
};
VarianceComponents variance_components(const SeedRuns& runs);  // throws as rate_interval

// What an evaluation of this size can decide. A method's mean over S seeds of n episodes has
// variance v(S, n) = seed_variance/S + episode_variance/(S n).
//   rate_half_width: t(S-1, 0.975) sqrt(v(S, n)), the half-width rate_interval reaches (normal
//     quantile for one seed; the binomial floor ignored);
//   difference_half_width: the same for A - B with S seeds each, t(2S-2) sqrt(2 v(S, n));
//   seeds_needed: the least S per method resolving a difference `delta` (rate units, 0.10 = 10
//     points) at alpha 0.05 two-sided with 80% power: 2 v(S, n) <= (delta / (z.975 + z.8))^2,
//     S = ceil(2 (z.975 + z.8)^2 (seed_variance + episode_variance/n) / delta^2), the large-sample
//     formula (DESIGN.md's n = 15.7 sd^2/delta^2, with sd^2 the variance of one seed's mean);
//   seeds_needed_4x_tasks: the same with 4n episodes per seed (4x the tasks).
// Throws DataError for no seeds, no episodes or delta <= 0.
struct PowerPlan {
  double rate_half_width = 0, difference_half_width = 0;
  long seeds_needed = 0, seeds_needed_4x_tasks = 0;
};
PowerPlan power(const VarianceComponents& components, double delta = 0.10);

}  // namespace cd
