#include "datasets/dataset.hpp"

#include <algorithm>
#include <cmath>

#include "core/error.hpp"
#include "core/rng.hpp"
#include "nn/model_settings.hpp"

namespace cd {

namespace {

// A sub-stream of train.seed (core/rng.hpp), so the split does not move when the subset does.
constexpr uint64_t kSubsetStream = 0x5012;

}  // namespace

Dataset::Dataset(EpisodeSet episodes, const DatasetOptions& options)
    : set_(std::move(episodes)), opt_(options) {
  if (opt_.history < 1 || opt_.stride < 1)
    throw ConfigError("history and history_stride must be >= 1");
  if (opt_.action_lags < 0) throw ConfigError("action lags must be >= 0");
  if (opt_.action_lags > 0 && opt_.action_head != "throttle_brake")
    throw ConfigError("previous actions need the recorded action as the target "
                      "(model.action_head = \"throttle_brake\")");
  if (opt_.action_head != "throttle_brake" && opt_.action_head != "target_speed")
    throw ConfigError("unknown action head '" + opt_.action_head + "'");
  if (opt_.signed_pedals && (set_.domain != kDrivingDomain || set_.action_dim < 2))
    throw ConfigError("model.pedals = \"signed\" learns driving's throttle - brake; " + set_.dir +
                      " holds " + set_.domain + " data");
  const int n = static_cast<int>(set_.episodes.size());
  val_episodes_ = choose_val_episodes(n, opt_.val_fraction, opt_.seed);
  // The target-speed label of step t is speed[t+1]: the last step has none, and a step whose
  // executed action was noise has none either (its next speed is the noise's).
  const int tail = opt_.action_head == "target_speed" ? 1 : 0;
  for (int e = 0; e < n; ++e) {
    auto& list = is_val_episode(e) ? val_ : train_;
    const PackedEpisode& ep = set_.episodes[e];
    for (int t = first_step(); t < ep.frames - tail; ++t)
      if (tail == 0 || expert_motion(ep, t, t + 1)) list.push_back({e, t});
  }
  if (train_.empty() && val_.empty())
    throw DataError("data folder '" + set_.dir + "' has no episode longer than " +
                    std::to_string(first_step() + tail) + " frames: no sample with a full " +
                    std::to_string(opt_.history) + "-frame history (history_stride " +
                    std::to_string(opt_.stride) + ")");
  // Both splits shrink by the same fraction; validation keeps at least one sample.
  Rng rng(derive_seed(opt_.seed, kSubsetStream));
  cap_splits(train_, val_, opt_.max_samples, rng, SubsetDraw::Full);
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
    action_at(s.episode, s.t, out.action);
  } else {
    out.action[0] = ep.speed[s.t + 1];
  }
  *out.speed_label = ep.speed[s.t];
  const size_t A = static_cast<size_t>(action_dim());
  for (int i = 1; i <= opt_.action_lags; ++i) action_at(s.episode, s.t - i, out.previous + A * (i - 1));
}

void Dataset::action_at(int e, int t, float* out) const {
  const size_t A = static_cast<size_t>(set_.action_dim);
  const float* a = set_.episodes[e].action.data() + A * t;
  if (opt_.signed_pedals)
    pedals_to_learned(a, set_.action_dim, out);
  else
    std::copy_n(a, A, out);
}

}  // namespace cd
