#include "learn/dataset.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>

#include "core/error.hpp"
#include "core/rng.hpp"

namespace cd {

namespace {

// Sub-streams of train.seed (core/rng.hpp), so the split does not move when the subset does.
constexpr uint64_t kSplitStream = 0x5011;
constexpr uint64_t kSubsetStream = 0x5012;

// A seeded subset of n samples, kept in their original order.
std::vector<SampleRef> subset(const std::vector<SampleRef>& all, size_t n, Rng& rng) {
  if (n >= all.size()) return all;
  std::vector<size_t> idx(all.size());
  std::iota(idx.begin(), idx.end(), size_t{0});
  shuffle(idx, rng);
  idx.resize(n);
  std::sort(idx.begin(), idx.end());
  std::vector<SampleRef> out;
  out.reserve(n);
  for (size_t i : idx) out.push_back(all[i]);
  return out;
}

}  // namespace

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

Dataset::Dataset(EpisodeSet episodes, const DatasetOptions& options)
    : set_(std::move(episodes)), opt_(options) {
  if (opt_.history < 1 || opt_.stride < 1)
    throw ConfigError("history and history_stride must be >= 1");
  if (opt_.action_head != "throttle_brake" && opt_.action_head != "target_speed")
    throw ConfigError("unknown action head '" + opt_.action_head + "'");
  const int n = static_cast<int>(set_.episodes.size());
  val_episodes_ = choose_val_episodes(n, opt_.val_fraction, opt_.seed);
  // The target-speed label of step t is speed[t+1]: the last step has none.
  const int tail = opt_.action_head == "target_speed" ? 1 : 0;
  for (int e = 0; e < n; ++e) {
    auto& list = is_val_episode(e) ? val_ : train_;
    for (int t = first_step(); t < set_.episodes[e].frames - tail; ++t) list.push_back({e, t});
  }
  if (train_.empty() && val_.empty())
    throw DataError("data folder '" + set_.dir + "' has no episode longer than " +
                    std::to_string(first_step() + tail) + " frames: no sample with a full " +
                    std::to_string(opt_.history) + "-frame history (history_stride " +
                    std::to_string(opt_.stride) + ")");
  const size_t total = train_.size() + val_.size();
  if (opt_.max_samples > 0 && static_cast<size_t>(opt_.max_samples) < total) {
    // Both splits shrink by the same fraction; validation keeps at least one sample.
    const double keep = static_cast<double>(opt_.max_samples) / static_cast<double>(total);
    size_t nv = val_.empty() ? 0 : std::max<size_t>(1, std::lround(keep * val_.size()));
    nv = std::min(nv, static_cast<size_t>(opt_.max_samples));
    size_t nt = static_cast<size_t>(opt_.max_samples) - nv;
    Rng rng(derive_seed(opt_.seed, kSubsetStream));
    train_ = subset(train_, nt, rng);
    val_ = subset(val_, nv, rng);
  }
  if (train_.empty())
    throw DataError("data folder '" + set_.dir + "' leaves no training sample (" +
                    std::to_string(val_.size()) + " validation samples); lower " +
                    "train.val_fraction or record more episodes");
}

bool Dataset::is_val_episode(int e) const {
  return std::binary_search(val_episodes_.begin(), val_episodes_.end(), e);
}

void Dataset::fill(const SampleRef& s, const SampleView& out) const {
  const PackedEpisode& ep = set_.episodes[s.episode];
  const size_t frame = set_.frame_values();
  for (int k = 0; k < opt_.history; ++k) {
    const int t = s.t - (opt_.history - 1 - k) * opt_.stride;  // k = 0 is the oldest
    set_.planes01(s.episode, t, out.image + static_cast<size_t>(k) * frame);
  }
  *out.speed_input = opt_.speed_input ? ep.speed[s.t] : 0.0f;
  *out.command = ep.command[s.t];
  if (opt_.action_head == "throttle_brake") {
    out.action[0] = ep.action[2 * static_cast<size_t>(s.t)];
    out.action[1] = ep.action[2 * static_cast<size_t>(s.t) + 1];
  } else {
    out.action[0] = ep.speed[s.t + 1];
  }
  *out.speed_label = ep.speed[s.t];
}

}  // namespace cd
