#include "inference/policy_runner.hpp"

#include <algorithm>

#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "nn/policy_net.hpp"

namespace cd {

void set_torch_threads(int threads) { torch::set_num_threads(std::max(1, threads)); }

struct PolicyRunner::Impl {
  Checkpoint ck;
  PolicyNet net{nullptr};
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
  const PolicyNetOptions o =
      policy_net_options(m.ck.model, in.history * in.channels, in.height, in.width);
  m.net = PolicyNet(o);
  const std::string path = dir + "/" + weights_file;
  std::string bytes;
  try {
    bytes = read_file_bytes(path);
  } catch (const IoError&) {
    throw DataError("checkpoint " + dir + " has no readable " + weights_file);
  }
  load_module_bytes(*m.net, bytes, torch::kCPU, path);
  m.net->eval();
  m.frame_values = static_cast<size_t>(in.channels) * in.height * in.width;
  m.image = torch::zeros({1, o.in_channels, in.height, in.width});
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

PolicyStep PolicyRunner::run(const uint8_t* const* frames, double speed, int command) {
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
  torch::Tensor a = m.net->forward(m.image, m.speed, m.command, false).action.contiguous();
  const float* v = a.data_ptr<float>();
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
