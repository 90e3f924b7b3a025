#pragma once
// The networks of one behaviour-cloning-family policy (bc-so, bc-oh and seed 001's methods):
// a PolicyNet acting on frames, plus, depending on the method,
//   memory      residual's memory-extraction module: a PolicyNet on the frame history whose
//               heads learn a_t - a_{t-i} (or a_t, a_{t-1} in the ablations); its backbone
//               feature, detached, is joined into the policy module;
//   adversary   fca's D: an MLP from [embedding, a_t] to a_{t-1};
//   controller  residual's "memory only: learned controller": an MLP from the detached memory
//               feature to a_t.
// The layout says which parts exist and their shapes; it follows from the method and the
// settings alone (policy_layout), so a run folder rebuilds its networks from its record.
// Saved as one archive; a policy without other parts is saved exactly as a bare PolicyNet.
//
// This header includes torch: include it only from the .cpp files that run the networks.
#include <string>
#include <vector>

#include <torch/torch.h>

#include "nn/model_settings.hpp"
#include "nn/policy_net.hpp"

namespace cd {

struct PolicyNetsLayout {
  std::string method;
  int action_dim = 2;           // A: learned components (signed pedals: one fewer than recorded)
  int history = 1;              // frames of the history input
  bool has_policy = true;       // false: residual memory-only controllers
  PolicyNetOptions policy;
  bool policy_sees_history = true;  // false: the policy module sees the current frame only
  bool has_memory = false;
  PolicyNetOptions memory;
  std::string memory_target;    // residual | action | previous
  int memory_heads = 0;         // residual: a_t - a_{t-i}, i = 1..memory_heads
  bool has_adversary = false;
  int adversary_hidden = 0;
  bool has_controller = false;
  // The squash of an action (policy, an action-predicting memory module and the controller;
  // squash_action): sigmoid for driving's throttle and brake in [0,1], sigmoid_tanh when a steer
  // in [-1,1] follows them, tanh for MuJoCo-Image's actions in [-1,1] and for signed pedals
  // (throttle - brake[, steer]), softplus for a target speed.
  std::string action_output = "sigmoid";
};

// The layout of `method` for frames of `frame_channels` x height x width, `action_dim`
// recorded components, data of `domain` (driving | mujoco: the action squash) (ConfigError for a setting
// the method cannot have).
PolicyNetsLayout policy_layout(const std::string& method, const ModelSettings& model,
                               const ResidualSettings& residual, const FcaSettings& fca,
                               int frame_channels, int height, int width, int action_dim,
                               const std::string& domain = "driving");

struct PolicyNets {
  explicit PolicyNets(const PolicyNetsLayout& layout);

  PolicyNetsLayout layout;
  PolicyNet policy{nullptr}, memory{nullptr};
  torch::nn::Sequential adversary{nullptr}, controller{nullptr};

  std::vector<torch::Tensor> parameters();
  std::vector<torch::Tensor> adversary_parameters();  // empty without an adversary
  void set_training(bool on);
  void to(const torch::Device& device);
  std::string save_bytes();
  // Throws DataError (naming `what`) when the bytes do not fit these networks.
  void load_bytes(const std::string& bytes, const torch::Device& device, const std::string& what);

  // The controller's action (with the layout's squash) from a memory feature.
  torch::Tensor control(const torch::Tensor& memory_feature);
  // The squash of an action output.
  torch::Tensor squash(const torch::Tensor& raw) const;

 private:
  bool bare() const { return !memory && !adversary && !controller; }
  std::shared_ptr<torch::nn::Module> holder_;
};

}  // namespace cd
