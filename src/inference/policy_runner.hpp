#pragma once
// A trained policy of the behaviour-cloning family (bc-so, bc-oh, residual, fca, keyframe, hd,
// dagger) loaded from its checkpoint folder, run on one observation at a time (closed loop, the
// copycat probe, attention maps), on the CPU or on eval.device. Torch stays inside the .cpp.
#include <cstdint>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "runs/checkpoint.hpp"

namespace cd {

struct PolicyStep {
  double throttle = 0, brake = 0;  // throttle_brake head, in [0,1] (driving only; MuJoCo's
                                   // action is PolicyRunner::last_action())
  double steer = 0;                // its third output, in [-1,1], when trained with steer
  double target_speed = std::numeric_limits<double>::quiet_NaN();  // target_speed head, m/s
  // The head's output as one number: throttle - brake, or the target speed.
  double scalar() const { return target_speed == target_speed ? target_speed : throttle - brake; }
};

// The methods whose run folders PolicyRunner loads (their checkpoint.json names one of them).
const std::vector<std::string>& policy_runner_methods();
bool is_policy_runner_method(const std::string& method);

// Grad-CAM's inputs for one observation: the last convolutional feature map A of the backbone
// of the network that acts, and the gradient of the head's output as one number (throttle -
// brake, or the target speed, before any clamping) with respect to A.
struct FeatureMapGradient {
  std::string module;  // "policy", or "memory" for residual's memory-only layouts
  int channels = 0, height = 0, width = 0;  // of A (batch 1)
  std::vector<float> activation;  // A: channels x height x width, row major
  std::vector<float> gradient;    // dOutput/dA, same layout
};

struct EpisodeSet;
// Throws DataError when the frames of a data folder (`set`, read from `dir`) differ in shape
// from what checkpoint `in` was trained on (the open-loop diagnostics run a policy on them).
void require_same_frames(const EpisodeSet& set, const InputFormat& in, const std::string& dir);

// torch's intra-op threads for this process (closed loop: 1, one worker process per core).
void set_torch_threads(int threads);

// Whether PolicyRunner's forward passes run on batch-invariant kernels (nn/kernels.hpp), for
// this process and the processes it forks: true (the default) gives every row of a batch the
// bytes it gets alone at batch 1 (what the inference process relies on,
// inference/batched_inference.hpp); false runs libtorch's own choice for the batch (bench and
// tests measure it). One row alone gets the same bytes either way.
void set_batch_invariant_inference(bool on);
bool batch_invariant_inference();

// One observation of run_batch(): as run()'s arguments.
struct PolicyInput {
  const uint8_t* const* frames = nullptr;
  double speed = 0;
  int command = 0;
  const float* previous = nullptr;
};

class PolicyRunner {
 public:
  // Reads dir/checkpoint.json and the weights file (best.pt by default), builds the network
  // from the checkpoint's own model settings, eval mode. Throws DataError for a missing or
  // damaged checkpoint, ConfigError when `expected_method` is given and differs.
  // `device` (auto | cpu | cuda, eval.device) is resolved at the first run(), not here: a
  // process that only checks a checkpoint before it forks its workers stays free of CUDA
  // (device/device.hpp). Weights trained on either device load on either.
  explicit PolicyRunner(const std::string& dir, const std::string& expected_method = "",
                        const std::string& weights_file = kBestFile,
                        const std::string& device = "cpu");
  ~PolicyRunner();
  PolicyRunner(const PolicyRunner&) = delete;
  PolicyRunner& operator=(const PolicyRunner&) = delete;

  const Checkpoint& checkpoint() const;
  int history() const;  // K frames per input
  int stride() const;   // simulation steps between them
  bool target_speed_head() const;

  // frames: history() pointers to C*H*W bytes (driving: 0/255 planes; MuJoCo: RGB; C x H x W
  // of the checkpoint's input),
  // oldest first. The speed is zeroed unless the model was trained with a speed input.
  // previous: the action executed one step before (A values); only residual's memory-only
  // residual controller reads it (a_{t-1} + the predicted residual); null means zeros.
  PolicyStep run(const uint8_t* const* frames, double speed, int command,
                 const float* previous = nullptr);
  // In a world process connected to batched inference (inference/batched_inference.hpp), run()
  // sends the observation to the inference process (same bytes, batch-invariant kernels).
  // run() on several observations (one row each, in order); `actions`, when given, receives
  // each row's last_action(). last_action() is then the last row's.
  // Slots 0 (the default): one forward pass of exactly these rows. A row's action can then
  // depend on how many rows ran beside it: libtorch's CPU kernels sum in another order for
  // some batch sizes (measured, tests/inference/test_policy_batch.cpp: batch 1 and 16 differ
  // from batch 2-9 in the last bits of some rows). Slots S > 0: every forward pass has exactly
  // S rows, the inputs in order and the rest padded with copies of the first, so a row's
  // action depends only on its own observation, never on the batch, its slot or the padding.
  std::vector<PolicyStep> run_batch(const std::vector<PolicyInput>& inputs,
                                    std::vector<std::vector<float>>* actions = nullptr);
  void set_batch_slots(int slots);  // >= 0; run() keeps its one-row pass only at 0
  int batch_slots() const;
  // run() that also fills `out` (autograd on, so slower than run(); the same action).
  PolicyStep run_with_gradient(const uint8_t* const* frames, double speed, int command,
                               const float* previous, FeatureMapGradient& out);
  // The action components of the last run() (A values as recorded: throttle, brake[, steer]
  // also for signed pedals, decoded; MuJoCo's action; the target speed for that head).
  const std::vector<float>& last_action() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace cd
