#pragma once
// Training samples of the behaviour-cloning methods over an EpisodeSet.
//
// A sample is (episode e, step t) with t >= (K-1)*stride, so its K frames t-(K-1)*stride, ...,
// t-stride, t are all real frames of the episode (never one frame repeated: a static history
// is itself a copycat trigger). Labels: the throttle_brake head learns action[t]; the
// target_speed head learns speed[t+1], the speed the expert reached one step later (so the
// last frame of an episode is no sample for it); the auxiliary head learns speed[t].
// With action_lags L > 0, a sample also carries the recorded actions a_{t-1} .. a_{t-L} and
// t >= L: at an episode's first frames the previous action is the recorded one, never a padded
// or invented one (seed 001's residual, fca and keyframe targets and inputs).
// Validation holds out whole episodes, chosen from the seed.
#include <algorithm>
#include <cstdint>
#include <string>
#include <vector>

#include "datasets/episode_set.hpp"
#include "datasets/split.hpp"

namespace cd {

struct DatasetOptions {
  int history = 1;                             // K
  int stride = 1;                              // steps between stacked frames
  std::string action_head = "throttle_brake";  // throttle_brake | target_speed
  bool speed_input = false;                    // false: the speed input is zero
  double val_fraction = 0.1;                   // of the episodes
  uint64_t seed = 0;                           // validation split and max_samples subset
  long max_samples = 0;                        // > 0: keep this many samples (both splits)
  int action_lags = 0;                         // L: previous recorded actions per sample
  // model.pedals = "signed": actions (label and previous) as throttle - brake[, steer]
  // (nn/model_settings.hpp); driving data only.
  bool signed_pedals = false;
};

// One sample's tensors, as flat arrays the trainer copies into a batch.
struct SampleView {
  float* image = nullptr;         // K*C*H*W planes of 0/1, oldest frame first
  float* speed_input = nullptr;   // 1
  int64_t* command = nullptr;     // 1
  float* action = nullptr;        // action_dim: (throttle, brake) or (next speed)
  float* speed_label = nullptr;   // 1: speed[t]
  float* previous = nullptr;      // L * A recorded actions: a_{t-1} first; null when L = 0
};

class Dataset {
 public:
  Dataset(EpisodeSet episodes, const DatasetOptions& options);  // throws DataError

  const EpisodeSet& episodes() const { return set_; }
  const DatasetOptions& options() const { return opt_; }
  int input_channels() const { return opt_.history * set_.channels; }
  // Components of a label as learned (a target speed: 1; signed pedals: one fewer than recorded).
  int action_dim() const {
    if (opt_.action_head != "throttle_brake") return 1;
    return opt_.signed_pedals ? set_.action_dim - 1 : set_.action_dim;
  }
  // The recorded action of step t of episode e as learned (action_dim() values).
  void action_at(int e, int t, float* out) const;
  size_t image_values() const { return static_cast<size_t>(opt_.history) * set_.frame_values(); }
  int first_step() const {  // first valid t
    return std::max((opt_.history - 1) * opt_.stride, opt_.action_lags);
  }

  const std::vector<SampleRef>& train() const { return train_; }
  const std::vector<SampleRef>& val() const { return val_; }
  const std::vector<int>& val_episodes() const { return val_episodes_; }  // indices, sorted
  bool is_val_episode(int e) const;

  void fill(const SampleRef& s, const SampleView& out) const;

 private:
  EpisodeSet set_;
  DatasetOptions opt_;
  std::vector<SampleRef> train_, val_;
  std::vector<int> val_episodes_;
};

}  // namespace cd
