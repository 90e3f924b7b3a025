#include "inference/policy_runner.hpp"

#include <algorithm>

#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "nn/policy_nets.hpp"

namespace cd {

void set_torch_threads(int threads) { torch::set_num_threads(std::max(1, threads)); }

struct PolicyRunner::Impl {
  Checkpoint ck;
  std::unique_ptr<PolicyNets> nets;
  std::vector<float> action;
  // Preallocated inputs: one observation, filled in place every step.
  torch::Tensor image, speed, command;
  size_t frame_values = 0;
};

PolicyRunner::PolicyRunner(const std::string& dir, const std::string& expected_method,
                           const std::string& weights_file)
    : impl_(std::make_unique<Impl>()) {
  Impl& m = *impl_;
  m.ck = require_checkpoint(dir);
  if (!expected_method.empty() && m.ck.method != expected_method)
    throw ConfigError("checkpoint " + dir + " was trained with method '" + m.ck.method +
                      "', not '" + expected_method + "'");
  const InputFormat& in = m.ck.input;
  m.nets = std::make_unique<PolicyNets>(policy_layout(m.ck.method, m.ck.model, m.ck.residual,
                                                      m.ck.fca, in.channels, in.height, in.width,
                                                      in.action_dim));
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

PolicyStep PolicyRunner::run(const uint8_t* const* frames, double speed, int command,
                             const float* previous) {
  Impl& m = *impl_;
  float* img = m.image.data_ptr<float>();
  for (int k = 0; k < m.ck.input.history; ++k) {
    const uint8_t* f = frames[k];
    float* dst = img + static_cast<size_t>(k) * m.frame_values;
    for (size_t i = 0; i < m.frame_values; ++i) dst[i] = f[i] ? 1.0f : 0.0f;
  }
  m.speed.data_ptr<float>()[0] = m.ck.model.speed_input ? static_cast<float>(speed) : 0.0f;
  m.command.data_ptr<int64_t>()[0] = std::clamp(command, 0, 3);
  torch::InferenceMode inference;
  PolicyNets& nets = *m.nets;
  const PolicyNetsLayout& l = nets.layout;
  torch::Tensor a;
  torch::Tensor memory_feature;
  PolicyOutput mem;
  if (nets.memory) {
    mem = nets.memory->forward(m.image, m.speed, m.command, false);
    memory_feature = mem.feature;
  }
  if (nets.policy) {
    const int C = m.ck.input.channels;
    torch::Tensor in = l.policy_sees_history ? m.image : m.image.narrow(1, m.image.size(1) - C, C);
    a = nets.policy->forward(in, m.speed, m.command, false, memory_feature).action;
  } else if (nets.controller) {
    a = nets.control(memory_feature);
  } else {
    // Memory only, residual controller: a_t = a_{t-1} + the predicted a_t - a_{t-1} (head 1).
    torch::Tensor prev = torch::zeros({1, l.action_dim});
    if (previous) std::copy_n(previous, l.action_dim, prev.data_ptr<float>());
    a = prev + mem.action.narrow(1, 0, l.action_dim);
  }
  a = a.contiguous();
  const float* v = a.data_ptr<float>();
  m.action.assign(v, v + a.size(1));
  PolicyStep step;
  if (target_speed_head()) {
    step.target_speed = std::max(0.0f, v[0]);
  } else {
    step.throttle = std::clamp(v[0], 0.0f, 1.0f);
    step.brake = std::clamp(v[1], 0.0f, 1.0f);
  }
  return step;
}

}  // namespace cd
