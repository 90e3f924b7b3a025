#pragma once
// The benchmarks' way to compare two loops on a busy machine (bench world, eval, env).
#include <cstdio>
#include <vector>

#include <nlohmann/json.hpp>

#include "bench/metrics.hpp"

namespace cd {

// Two loops timed over the same slices, A B A B ...: a machine that slows down (another
// process, a frequency change) slows both loops of a slice alike, so the per-slice ratio
// holds where a ratio of two separate runs does not. The median ratio is the figure; the
// spread says how far to trust it.
struct Interleaved {
  std::vector<double> rate_a, rate_b, ratios;  // per slice; ratio = b / a
  long steps_a = 0, steps_b = 0;
  double seconds_a = 0, seconds_b = 0;

  void add(long sa, double ta, long sb, double tb) {
    steps_a += sa;
    steps_b += sb;
    seconds_a += ta;
    seconds_b += tb;
    rate_a.push_back(sa / ta);
    rate_b.push_back(sb / tb);
    ratios.push_back(rate_b.back() / rate_a.back());
  }
  double median() const { return *quantile(ratios, 0.5); }
  nlohmann::json spread_json() const {
    return {{"ratio_min", *quantile(ratios, 0.0)},
            {"ratio_q25", *quantile(ratios, 0.25)},
            {"ratio_q75", *quantile(ratios, 0.75)},
            {"ratio_max", *quantile(ratios, 1.0)},
            {"slices", static_cast<long>(ratios.size())}};
  }
  void print_spread() const {
    std::printf("  ratio       %10.3f  median of %zu slices (quartiles %.3f .. %.3f, range "
                "%.3f .. %.3f)\n",
                median(), ratios.size(), *quantile(ratios, 0.25), *quantile(ratios, 0.75),
                *quantile(ratios, 0.0), *quantile(ratios, 1.0));
  }
};

}  // namespace cd
