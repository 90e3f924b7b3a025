#include "datasets/split.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>

namespace cd {

namespace {
constexpr uint64_t kSplitStream = 0x5011;  // a sub-stream of train.seed (core/rng.hpp)
}

std::vector<int> choose_val_episodes(int episodes, double val_fraction, uint64_t seed) {
  if (episodes < 2 || val_fraction <= 0) return {};
  int n = static_cast<int>(std::lround(val_fraction * episodes));
  n = std::clamp(n, 1, episodes - 1);
  std::vector<int> order(episodes);
  std::iota(order.begin(), order.end(), 0);
  Rng rng(derive_seed(seed, kSplitStream));
  shuffle(order, rng);
  order.resize(n);
  std::sort(order.begin(), order.end());
  return order;
}

void cap_splits(std::vector<SampleRef>& train, std::vector<SampleRef>& val, long max, Rng& rng,
                SubsetDraw draw) {
  const size_t total = train.size() + val.size();
  if (max <= 0 || static_cast<size_t>(max) >= total) return;
  const double keep = static_cast<double>(max) / static_cast<double>(total);
  size_t nv = val.empty() ? 0 : std::max<size_t>(1, std::lround(keep * val.size()));
  nv = std::min(nv, static_cast<size_t>(max));
  train = subset_in_order(train, static_cast<size_t>(max) - nv, rng, draw);
  val = subset_in_order(val, nv, rng, draw);
}

}  // namespace cd
