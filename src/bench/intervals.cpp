#include "bench/intervals.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>

#include <boost/math/distributions/chi_squared.hpp>
#include <boost/math/distributions/normal.hpp>
#include <boost/math/distributions/students_t.hpp>

#include "core/error.hpp"
#include "core/rng.hpp"

namespace cd {
namespace {

constexpr double kInfinity = std::numeric_limits<double>::infinity();

double mean_of(const std::vector<double>& v) {
  return std::accumulate(v.begin(), v.end(), 0.0) / static_cast<double>(v.size());
}

// Sample variance (n - 1); 0 for fewer than two values.
double sample_variance(const std::vector<double>& v) {
  if (v.size() < 2) return 0;
  const double m = mean_of(v);
  double ss = 0;
  for (double x : v) ss += (x - m) * (x - m);
  return ss / static_cast<double>(v.size() - 1);
}

double normal_quantile(double p) {
  return boost::math::quantile(boost::math::normal_distribution<double>(), p);
}

// The 97.5% quantile of Student t at df (the normal one for an infinite df).
double t975(double df) {
  if (std::isinf(df)) return normal_quantile(0.975);
  return boost::math::quantile(boost::math::students_t_distribution<double>(df), 0.975);
}

// Linear interpolation between order statistics (numpy's default percentile).
double sorted_quantile(const std::vector<double>& sorted, double q) {
  const double h = q * static_cast<double>(sorted.size() - 1);
  const size_t i = static_cast<size_t>(h);
  if (i + 1 >= sorted.size()) return sorted.back();
  return sorted[i] + (h - static_cast<double>(i)) * (sorted[i + 1] - sorted[i]);
}

// Throws DataError unless `runs` is one method on one condition that the intervals can use.
void check_runs(const SeedRuns& runs) {
  if (runs.empty()) throw DataError("intervals: no training seeds");
  const size_t tasks = runs.front().per_task.size();
  if (tasks == 0) throw DataError("intervals: a seed has no tasks");
  for (const SeedOutcomes& seed : runs) {
    if (seed.per_task.size() != tasks)
      throw DataError("intervals: seeds ran different numbers of tasks (" +
                      std::to_string(seed.per_task.size()) + " and " + std::to_string(tasks) + ")");
    if (seed.trials < 1) throw DataError("intervals: trials per task must be at least 1");
    for (double v : seed.per_task)
      if (!(v >= 0 && v <= 1)) throw DataError("intervals: a task's rate is outside [0,1]");
  }
}

long episodes_of(const SeedOutcomes& seed) {
  return static_cast<long>(seed.per_task.size()) * seed.trials;
}

// What a method's interval needs from its seeds.
struct SeedLevel {
  std::vector<double> values;  // per seed: mean over conditions of its mean over tasks
  double floor_variance = 0;   // the binomial floor of the variance of mean(values)
  long episodes = 0;
};

// Per condition the pooled rate, shrunk as Agresti-Coull so that it is never 0 or 1, gives each
// seed's condition mean a variance of at least p(1-p)/n_s; the floor adds these up through the
// means over conditions and over seeds.
SeedLevel seed_level(const std::vector<SeedRuns>& by_condition) {
  if (by_condition.empty()) throw DataError("intervals: no conditions");
  const size_t seeds = by_condition.front().size();
  const double conditions = static_cast<double>(by_condition.size());
  SeedLevel level;
  level.values.assign(seeds, 0.0);
  for (const SeedRuns& runs : by_condition) {
    check_runs(runs);
    if (runs.size() != seeds)
      throw DataError("intervals: a method has different seed counts across conditions");
    double successes = 0, trials = 0, inverse_episodes = 0;
    for (size_t s = 0; s < seeds; ++s) {
      const double n = static_cast<double>(episodes_of(runs[s]));
      const double seed_mean = mean_of(runs[s].per_task);
      level.values[s] += seed_mean / conditions;
      successes += seed_mean * n;
      trials += n;
      inverse_episodes += 1 / n;
      level.episodes += episodes_of(runs[s]);
    }
    const double p = (successes + 2) / (trials + 4);
    level.floor_variance += p * (1 - p) * inverse_episodes;
  }
  level.floor_variance /= conditions * conditions * static_cast<double>(seeds * seeds);
  return level;
}

// A mean with the variance of its estimate and that variance's degrees of freedom.
struct Estimate {
  double mean = 0, variance = 0, df = kInfinity;
  long episodes = 0;
};

// V = max(s^2/S, c F), df S-1. Seed means that agree more closely than binomial noise allows
// do so by chance, and s^2 is not believed below c F, c the lower quartile of chi2(S-1)/(S-1):
// the value the episode noise alone exceeds 3 times in 4 (c = 1 covered 98-99% at 3 seeds
// and 10 seeds without seed effects). One seed: F alone, with the normal quantile.
Estimate estimate(const SeedLevel& level) {
  const double seeds = static_cast<double>(level.values.size());
  Estimate e;
  e.mean = mean_of(level.values);
  e.episodes = level.episodes;
  if (level.values.size() == 1) {
    e.variance = level.floor_variance;
    return e;
  }
  e.df = seeds - 1;
  const boost::math::chi_squared_distribution<double> chi2(e.df);
  const double c = boost::math::quantile(chi2, 0.25) / e.df;
  e.variance = std::max(sample_variance(level.values) / seeds, c * level.floor_variance);
  return e;
}

// Welch-Satterthwaite: the df of a sum of independent variance estimates.
double welch_df(const Estimate& a, const Estimate& b) {
  double denominator = 0;
  for (const Estimate* e : {&a, &b})
    if (!std::isinf(e->df)) denominator += e->variance * e->variance / e->df;
  if (denominator == 0) return kInfinity;
  const double v = a.variance + b.variance;
  return v * v / denominator;
}

// P(a > b) + P(a == b)/2 over all pairs of A's and B's values on one task.
double mann_whitney_share(const SeedRuns& a, const SeedRuns& b, size_t task) {
  double wins = 0;
  for (const SeedOutcomes& sa : a)
    for (const SeedOutcomes& sb : b) {
      const double x = sa.per_task[task], y = sb.per_task[task];
      wins += x > y ? 1.0 : x == y ? 0.5 : 0.0;
    }
  return wins / static_cast<double>(a.size() * b.size());
}

double probability_of_improvement(const SeedRuns& a, const SeedRuns& b) {
  const size_t tasks = a.front().per_task.size();
  double sum = 0;
  for (size_t t = 0; t < tasks; ++t) sum += mann_whitney_share(a, b, t);
  return sum / static_cast<double>(tasks);
}

}  // namespace

Interval rate_interval(const SeedRuns& runs) {
  const Estimate e = estimate(seed_level({runs}));
  // Wilson's score interval at the effective number of episodes n = m(1-m)/V (the episodes
  // whose binomial variance equals V), t for z: asymmetric near 0 and 1, where seed means are
  // skewed, and never empty of m. At m = 0 or 1, m(1-m) is taken 1/(2N) from the bound.
  const double q = t975(e.df), episodes = static_cast<double>(e.episodes);
  const double m = e.mean, edge = std::clamp(m, 0.5 / episodes, 1 - 0.5 / episodes);
  const double n = edge * (1 - edge) / e.variance, shrink = 1 + q * q / n;
  const double centre = (m + q * q / (2 * n)) / shrink;
  const double half = q * std::sqrt(m * (1 - m) / n + q * q / (4 * n * n)) / shrink;
  Interval out;
  out.mean = m;
  out.lo = std::max(0.0, centre - half);
  out.hi = std::min(1.0, centre + half);
  out.seeds = static_cast<int>(runs.size());
  out.episodes = e.episodes;
  out.episode_only = runs.size() == 1;
  return out;
}

std::string verdict_text(Verdict verdict) {
  switch (verdict) {
    case Verdict::a_better: return "A better";
    case Verdict::b_better: return "B better";
    case Verdict::not_resolved: break;
  }
  return "not resolved";
}

Comparison compare(const SeedRuns& a, const SeedRuns& b) {
  return compare(std::vector<SeedRuns>{a}, std::vector<SeedRuns>{b});
}

Comparison compare(const std::vector<SeedRuns>& a_by_condition,
                   const std::vector<SeedRuns>& b_by_condition) {
  if (a_by_condition.size() != b_by_condition.size())
    throw DataError("intervals: A and B have different numbers of conditions");
  const Estimate a = estimate(seed_level(a_by_condition));
  const Estimate b = estimate(seed_level(b_by_condition));
  double p_sum = 0;
  for (size_t c = 0; c < a_by_condition.size(); ++c) {
    if (a_by_condition[c].front().per_task.size() != b_by_condition[c].front().per_task.size())
      throw DataError("intervals: A and B ran different tasks on a condition");
    p_sum += probability_of_improvement(a_by_condition[c], b_by_condition[c]);
  }
  Comparison out;
  out.difference = a.mean - b.mean;
  const double half = t975(welch_df(a, b)) * std::sqrt(a.variance + b.variance);
  out.lo = std::max(-1.0, out.difference - half);
  out.hi = std::min(1.0, out.difference + half);
  out.p_improvement = p_sum / static_cast<double>(a_by_condition.size());
  out.verdict = out.lo > 0   ? Verdict::a_better
                : out.hi < 0 ? Verdict::b_better
                             : Verdict::not_resolved;
  out.episode_only = std::isinf(a.df) || std::isinf(b.df);
  return out;
}

double interquartile_mean(std::vector<double> values) {
  if (values.empty()) throw DataError("interquartile mean: no values");
  std::sort(values.begin(), values.end());
  const size_t cut = values.size() / 4;
  const auto first = values.begin() + static_cast<long>(cut);
  const auto last = values.end() - static_cast<long>(cut);
  return std::accumulate(first, last, 0.0) / static_cast<double>(last - first);
}

namespace {

// The returns of one method, checked: at least one seed, each with episodes.
void check_returns(const std::vector<std::vector<double>>& returns_by_seed) {
  if (returns_by_seed.empty()) throw DataError("interquartile mean: no training seeds");
  for (const std::vector<double>& returns : returns_by_seed)
    if (returns.empty()) throw DataError("interquartile mean: a seed has no episodes");
}

// One two-level bootstrap draw into `drawn` (cleared first): S seeds with replacement, then each
// drawn seed's episodes with replacement.
void draw_two_level(const std::vector<std::vector<double>>& returns_by_seed, Rng& rng,
                    std::vector<double>& drawn) {
  drawn.clear();
  const size_t seeds = returns_by_seed.size();
  for (size_t i = 0; i < seeds; ++i) {
    const std::vector<double>& returns = returns_by_seed[rng.below(seeds)];
    for (size_t j = 0; j < returns.size(); ++j) drawn.push_back(returns[rng.below(returns.size())]);
  }
}

std::vector<double> all_returns(const std::vector<std::vector<double>>& returns_by_seed) {
  std::vector<double> all;
  for (const std::vector<double>& returns : returns_by_seed)
    all.insert(all.end(), returns.begin(), returns.end());
  return all;
}

}  // namespace

IqmInterval iqm_interval(const std::vector<std::vector<double>>& returns_by_seed, uint64_t seed,
                         int resamples) {
  check_returns(returns_by_seed);
  if (resamples < 1) throw ConfigError("--resamples must be at least 1");
  std::vector<double> iqms, drawn;
  iqms.reserve(static_cast<size_t>(resamples));
  for (int b = 0; b < resamples; ++b) {
    Rng rng(derive_seed(seed, static_cast<uint64_t>(b)));
    draw_two_level(returns_by_seed, rng, drawn);
    iqms.push_back(interquartile_mean(drawn));
  }
  std::sort(iqms.begin(), iqms.end());
  IqmInterval out;
  out.iqm = interquartile_mean(all_returns(returns_by_seed));
  out.lo = sorted_quantile(iqms, 0.025);
  out.hi = sorted_quantile(iqms, 0.975);
  out.resamples = resamples;
  return out;
}

IqmComparison compare_iqm(const std::vector<std::vector<double>>& a_by_seed,
                          const std::vector<std::vector<double>>& b_by_seed, uint64_t seed,
                          int resamples) {
  check_returns(a_by_seed);
  check_returns(b_by_seed);
  if (resamples < 1) throw ConfigError("--resamples must be at least 1");
  std::vector<double> differences, drawn;
  differences.reserve(static_cast<size_t>(resamples));
  for (int b = 0; b < resamples; ++b) {
    Rng rng(derive_seed(seed, static_cast<uint64_t>(b)));
    draw_two_level(a_by_seed, rng, drawn);
    const double a = interquartile_mean(drawn);
    draw_two_level(b_by_seed, rng, drawn);
    differences.push_back(a - interquartile_mean(drawn));
  }
  std::sort(differences.begin(), differences.end());
  IqmComparison out;
  out.a = interquartile_mean(all_returns(a_by_seed));
  out.b = interquartile_mean(all_returns(b_by_seed));
  out.difference = out.a - out.b;
  out.lo = sorted_quantile(differences, 0.025);
  out.hi = sorted_quantile(differences, 0.975);
  out.resamples = resamples;
  out.verdict = out.lo > 0 ? Verdict::a_better : out.hi < 0 ? Verdict::b_better
                                                            : Verdict::not_resolved;
  // rliable's probability of improvement over the seed pairs, each seed by its own IQM.
  double wins = 0;
  for (const std::vector<double>& sa : a_by_seed)
    for (const std::vector<double>& sb : b_by_seed) {
      const double ia = interquartile_mean(sa), ib = interquartile_mean(sb);
      wins += ia > ib ? 1.0 : ia == ib ? 0.5 : 0.0;
    }
  out.p_improvement = wins / static_cast<double>(a_by_seed.size() * b_by_seed.size());
  return out;
}

VarianceComponents variance_components(const SeedRuns& runs) {
  check_runs(runs);
  std::vector<double> seed_means;
  VarianceComponents out;
  for (const SeedOutcomes& seed : runs) {
    const double p = mean_of(seed.per_task), n = static_cast<double>(episodes_of(seed));
    seed_means.push_back(p);
    out.episode_variance += n > 1 ? p * (1 - p) * n / (n - 1) : 0.0;
    out.episodes_per_seed += n;
  }
  const double seeds = static_cast<double>(runs.size());
  out.seeds = static_cast<int>(runs.size());
  out.episode_variance /= seeds;
  out.episodes_per_seed /= seeds;
  out.seed_variance =
      std::max(0.0, sample_variance(seed_means) - out.episode_variance / out.episodes_per_seed);
  return out;
}

PowerPlan power(const VarianceComponents& c, double delta) {
  if (c.seeds < 1 || c.episodes_per_seed <= 0 || !(delta > 0))
    throw DataError("power: needs at least one seed with episodes and a positive difference");
  const double seeds = c.seeds;
  // The variance of one seed's mean at n episodes, and of a method's mean over S seeds.
  const auto seed_mean_variance = [&](double n) {
    return c.seed_variance + c.episode_variance / n;
  };
  const double method_variance = seed_mean_variance(c.episodes_per_seed) / seeds;
  const double z_sum = normal_quantile(0.975) + normal_quantile(0.8);
  const auto seeds_for = [&](double n) {
    return static_cast<long>(std::ceil(2 * z_sum * z_sum * seed_mean_variance(n) / delta / delta));
  };
  PowerPlan out;
  out.rate_half_width = t975(c.seeds > 1 ? seeds - 1 : kInfinity) * std::sqrt(method_variance);
  out.difference_half_width =
      t975(c.seeds > 1 ? 2 * seeds - 2 : kInfinity) * std::sqrt(2 * method_variance);
  out.seeds_needed = seeds_for(c.episodes_per_seed);
  out.seeds_needed_4x_tasks = seeds_for(4 * c.episodes_per_seed);
  return out;
}

}  // namespace cd
