#include "inference/policy_runner.hpp"

#include <algorithm>

#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "data/mujoco_episode.hpp"
#include "datasets/episode_set.hpp"
#include "nn/policy_nets.hpp"
#include "device/device.hpp"

namespace cd {

void set_torch_threads(int threads) { torch::set_num_threads(std::max(1, threads)); }

void require_same_frames(const EpisodeSet& set, const InputFormat& in, const std::string& dir) {
  if (set.channels != in.channels || set.height != in.height || set.width != in.width)
    throw DataError("data in " + dir + " has " + std::to_string(set.channels) + "x" +
                    std::to_string(set.height) + "x" + std::to_string(set.width) +
                    " frames, the checkpoint was trained on " + std::to_string(in.channels) +
                    "x" + std::to_string(in.height) + "x" + std::to_string(in.width));
}

struct PolicyRunner::Impl {
  Checkpoint ck;
  std::unique_ptr<PolicyNets> nets;
  std::vector<float> action;
  std::vector<float> learned;  // signed pedals: the network's output before decoding
  // Preallocated inputs: one observation, filled in place every step.
  torch::Tensor image, speed, command;
  size_t frame_values = 0;
  std::string wanted_device = "cpu";  // eval.device, resolved by place() at the first run
  bool placed = false;
  torch::Device device = torch::kCPU;

  // Moves the networks to the wanted device, once.
  void place();

  // Writes one observation into the preallocated inputs.
  void fill(const uint8_t* const* frames, double speed_value, int command_value);
  // The action of the network that acts (B = 1); with `feature_map`, also its backbone's last
  // convolutional map and which module that is.
  torch::Tensor act(const float* previous, torch::Tensor* feature_map, std::string* module);
  // Keeps the action components and turns them into controls.
  PolicyStep step(torch::Tensor a, bool target_speed_head);
};

PolicyRunner::PolicyRunner(const std::string& dir, const std::string& expected_method,
                           const std::string& weights_file, const std::string& device)
    : impl_(std::make_unique<Impl>()) {
  Impl& m = *impl_;
  m.wanted_device = device;
  m.ck = require_checkpoint(dir);
  if (!expected_method.empty() && m.ck.method != expected_method)
    throw ConfigError("checkpoint " + dir + " was trained with method '" + m.ck.method +
                      "', not '" + expected_method + "'");
  const InputFormat& in = m.ck.input;
  m.nets = std::make_unique<PolicyNets>(policy_layout(m.ck.method, m.ck.model, m.ck.residual,
                                                      m.ck.fca, in.channels, in.height, in.width,
                                                      in.action_dim, in.domain));
  if (!in.action_output.empty() && in.action_output != m.nets->layout.action_output)
    throw DataError("checkpoint " + dir + " squashes its actions with " + in.action_output +
                    ", which this build does not give its networks (" +
                    m.nets->layout.action_output + ")");
  const std::string path = dir + "/" + weights_file;
  std::string bytes;
  try {
    bytes = read_file_bytes(path);
  } catch (const IoError&) {
    throw DataError("checkpoint " + dir + " has no readable " + weights_file);
  }
  m.nets->load_bytes(bytes, torch::kCPU, path);
  m.nets->set_training(false);
  m.frame_values = static_cast<size_t>(in.channels) * in.height * in.width;
  m.image = torch::zeros({1, in.history * in.channels, in.height, in.width});
  m.speed = torch::zeros({1, 1});
  m.command = torch::zeros({1}, torch::TensorOptions().dtype(torch::kInt64));
}

PolicyRunner::~PolicyRunner() = default;

const Checkpoint& PolicyRunner::checkpoint() const { return impl_->ck; }
int PolicyRunner::history() const { return impl_->ck.input.history; }
int PolicyRunner::stride() const { return impl_->ck.input.stride; }
bool PolicyRunner::target_speed_head() const {
  return impl_->ck.model.action_head == "target_speed";
}

const std::vector<float>& PolicyRunner::last_action() const { return impl_->action; }

const std::vector<std::string>& policy_runner_methods() {
  static const std::vector<std::string> names = {"bc-so", "bc-oh", "residual", "fca",
                                                 "keyframe", "hd", "dagger"};
  return names;
}

void PolicyRunner::Impl::fill(const uint8_t* const* frames, double speed_value, int command_value) {
  float* img = image.data_ptr<float>();
  const FrameLayout layout = ck.input.domain == kMujocoDomain ? FrameLayout::Bytes
                                                              : FrameLayout::BitPlanes;
  for (int k = 0; k < ck.input.history; ++k)
    frame_bytes_to_unit(layout, frames[k], frame_values,
                        img + static_cast<size_t>(k) * frame_values);
  speed.data_ptr<float>()[0] = ck.model.speed_input ? static_cast<float>(speed_value) : 0.0f;
  command.data_ptr<int64_t>()[0] = std::clamp(command_value, 0, 3);
}

void PolicyRunner::Impl::place() {
  if (placed) return;
  device = torch_device(resolve_device(wanted_device, "eval.device"));
  if (device != torch::Device(torch::kCPU)) nets->to(device);
  placed = true;
}

torch::Tensor PolicyRunner::Impl::act(const float* previous, torch::Tensor* feature_map,
                                      std::string* module) {
  place();
  const PolicyNetsLayout& l = nets->layout;
  // The inputs on the networks' device (the same tensors on the CPU).
  const torch::Tensor image = this->image.to(device), speed = this->speed.to(device),
                      command = this->command.to(device);
  torch::Tensor a;
  torch::Tensor memory_feature;
  PolicyOutput mem;
  if (nets->memory) {
    mem = nets->memory->forward(image, speed, command, false);
    memory_feature = mem.feature;
  }
  if (nets->policy) {
    // The memory feature is an input of the policy module (detached, as in training).
    if (memory_feature.defined()) memory_feature = memory_feature.detach();
    const int C = ck.input.channels;
    torch::Tensor in = l.policy_sees_history ? image : image.narrow(1, image.size(1) - C, C);
    PolicyOutput out = nets->policy->forward(in, speed, command, false, memory_feature);
    a = out.action;
    if (feature_map) {
      *feature_map = out.feature_map;
      *module = "policy";
    }
  } else {
    if (feature_map) {
      *feature_map = mem.feature_map;
      *module = "memory";
    }
    if (nets->controller) {
      a = nets->control(memory_feature);
    } else {
      // Memory only, residual controller: a_t = a_{t-1} + the predicted a_t - a_{t-1} (head 1),
      // in the space the action is learned in (model.pedals).
      torch::Tensor prev = torch::zeros({1, l.action_dim});
      if (previous && signed_pedals(ck.model, ck.input.domain))
        pedals_to_learned(previous, ck.input.action_dim, prev.data_ptr<float>());
      else if (previous)
        std::copy_n(previous, l.action_dim, prev.data_ptr<float>());
      a = prev.to(device) + mem.action.narrow(1, 0, l.action_dim);
    }
  }
  return a;
}

PolicyStep PolicyRunner::Impl::step(torch::Tensor a, bool target_speed_head) {
  a = a.detach().to(torch::kCPU).contiguous();
  const float* v = a.data_ptr<float>();
  if (!target_speed_head && signed_pedals(ck.model, ck.input.domain)) {
    // throttle - brake[, steer] -> throttle, brake[, steer]
    learned.assign(v, v + a.size(1));
    action.resize(static_cast<size_t>(ck.input.action_dim));
    pedals_to_recorded(learned.data(), ck.input.action_dim, action.data());
  } else {
    action.assign(v, v + a.size(1));
  }
  v = action.data();
  PolicyStep s;
  if (target_speed_head) {
    s.target_speed = std::max(0.0f, v[0]);
  } else if (ck.input.domain != kMujocoDomain) {  // MuJoCo: last_action() is the action
    s.throttle = std::clamp(v[0], 0.0f, 1.0f);
    s.brake = std::clamp(v[1], 0.0f, 1.0f);
    if (action.size() >= 3) s.steer = std::clamp(v[2], -1.0f, 1.0f);
  }
  return s;
}

PolicyStep PolicyRunner::run(const uint8_t* const* frames, double speed, int command,
                             const float* previous) {
  Impl& m = *impl_;
  m.fill(frames, speed, command);
  torch::InferenceMode inference;
  return m.step(m.act(previous, nullptr, nullptr), target_speed_head());
}

PolicyStep PolicyRunner::run_with_gradient(const uint8_t* const* frames, double speed,
                                           int command, const float* previous,
                                           FeatureMapGradient& out) {
  Impl& m = *impl_;
  m.fill(frames, speed, command);
  torch::AutoGradMode grad_on(true);
  torch::Tensor map;
  torch::Tensor a = m.act(previous, &map, &out.module);
  // The head's output as one number, unclamped: the target speed, or throttle - brake (signed
  // pedals: their one value).
  torch::Tensor scalar = target_speed_head() || signed_pedals(m.ck.model, m.ck.input.domain)
                             ? a.select(1, 0)
                             : a.select(1, 0) - a.select(1, 1);
  torch::Tensor g = torch::autograd::grad({scalar.sum()}, {map}, {}, /*retain_graph=*/false,
                                          /*create_graph=*/false, /*allow_unused=*/true)[0];
  if (!g.defined()) g = torch::zeros_like(map);
  map = map.detach().to(torch::kCPU).contiguous();
  g = g.to(torch::kCPU).contiguous();
  out.channels = static_cast<int>(map.size(1));
  out.height = static_cast<int>(map.size(2));
  out.width = static_cast<int>(map.size(3));
  out.activation.assign(map.data_ptr<float>(), map.data_ptr<float>() + map.numel());
  out.gradient.assign(g.data_ptr<float>(), g.data_ptr<float>() + g.numel());
  return m.step(a, target_speed_head());
}

}  // namespace cd
