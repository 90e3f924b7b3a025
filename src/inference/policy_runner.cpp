#include "inference/policy_runner.hpp"

#include <algorithm>

#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "data/mujoco_episode.hpp"
#include "datasets/episode_set.hpp"
#include "nn/policy_nets.hpp"
#include "sense/camera.hpp"
#include "device/device.hpp"
#include "inference/batched_inference.hpp"
#include "nn/kernels.hpp"

namespace cd {

void set_torch_threads(int threads) { torch::set_num_threads(std::max(1, threads)); }

namespace {
bool invariant_inference = true;
}
void set_batch_invariant_inference(bool on) { invariant_inference = on; }
bool batch_invariant_inference() { return invariant_inference; }

void require_same_frames(const EpisodeSet& set, const InputFormat& in, const std::string& dir) {
  if (set.channels != in.channels || set.height != in.height || set.width != in.width)
    throw DataError("data in " + dir + " has " + std::to_string(set.channels) + "x" +
                    std::to_string(set.height) + "x" + std::to_string(set.width) +
                    " frames, the checkpoint was trained on " + std::to_string(in.channels) +
                    "x" + std::to_string(in.height) + "x" + std::to_string(in.width));
}

struct PolicyRunner::Impl {
  Checkpoint ck;
  std::string remote_key;  // what the inference process loads: dir, method, weights, device
  std::unique_ptr<PolicyNets> nets;
  std::vector<float> action;
  std::vector<float> learned;  // signed pedals: the network's output before decoding
  // Preallocated inputs of `rows` observations, filled in place every step (run(): one).
  torch::Tensor image, speed, command;
  int rows = 0;
  int slots = 0;  // set_batch_slots
  size_t frame_values = 0;
  std::string wanted_device = "cpu";  // eval.device, resolved by place() at the first run
  bool placed = false;
  torch::Device device = torch::kCPU;

  // Moves the networks to the wanted device, once.
  void place();

  // Sizes the preallocated inputs to n observations.
  void resize(int n);
  // Writes one observation into row `row` of the preallocated inputs.
  void fill(int row, const uint8_t* const* frames, double speed_value, int command_value);
  // The actions of the network that acts (one row per observation); previous[r]: row r's
  // previous action or null. With `feature_map`, also its backbone's last convolutional map and
  // which module that is.
  torch::Tensor act(const std::vector<const float*>& previous, torch::Tensor* feature_map,
                    std::string* module);
  // Keeps the action components of one row (A values, on the CPU) and turns them into controls.
  PolicyStep step(const float* v, int64_t n, bool target_speed_head);
};

PolicyRunner::PolicyRunner(const std::string& dir, const std::string& expected_method,
                           const std::string& weights_file, const std::string& device)
    : impl_(std::make_unique<Impl>()) {
  Impl& m = *impl_;
  m.wanted_device = device;
  m.remote_key = dir + "\n" + expected_method + "\n" + weights_file + "\n" + device;
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
  m.resize(1);
}

void PolicyRunner::Impl::resize(int n) {
  if (n == rows) return;
  const InputFormat& in = ck.input;
  image = torch::zeros({n, in.history * in.channels, in.height, in.width});
  speed = torch::zeros({n, 1});
  command = torch::zeros({n}, torch::TensorOptions().dtype(torch::kInt64));
  rows = n;
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

bool is_policy_runner_method(const std::string& method) {
  const auto& names = policy_runner_methods();
  return std::find(names.begin(), names.end(), method) != names.end();
}

void PolicyRunner::Impl::fill(int row, const uint8_t* const* frames, double speed_value,
                              int command_value) {
  float* img = image.data_ptr<float>() + static_cast<size_t>(row) * ck.input.history * frame_values;
  // RGB bytes (MuJoCo-Image, the driving camera) or the BEV's 0/255 planes.
  const FrameLayout layout =
      ck.input.domain == kMujocoDomain || ck.input.channel_names == camera_channel_names()
          ? FrameLayout::Bytes
          : FrameLayout::BitPlanes;
  for (int k = 0; k < ck.input.history; ++k)
    frame_bytes_to_unit(layout, frames[k], frame_values,
                        img + static_cast<size_t>(k) * frame_values);
  speed.data_ptr<float>()[row] = ck.model.speed_input ? static_cast<float>(speed_value) : 0.0f;
  command.data_ptr<int64_t>()[row] = std::clamp(command_value, 0, 3);
}

void PolicyRunner::Impl::place() {
  if (placed) return;
  device = torch_device(resolve_device(wanted_device, "eval.device"));
  if (device != torch::Device(torch::kCPU)) nets->to(device);
  placed = true;
}

torch::Tensor PolicyRunner::Impl::act(const std::vector<const float*>& previous,
                                      torch::Tensor* feature_map, std::string* module) {
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
      torch::Tensor prev = torch::zeros({rows, l.action_dim});
      for (int r = 0; r < rows; ++r) {
        const float* p = previous[static_cast<size_t>(r)];
        float* row = prev.data_ptr<float>() + static_cast<size_t>(r) * l.action_dim;
        if (p && signed_pedals(ck.model, ck.input.domain))
          pedals_to_learned(p, ck.input.action_dim, row);
        else if (p)
          std::copy_n(p, l.action_dim, row);
      }
      a = prev.to(device) + mem.action.narrow(1, 0, l.action_dim);
    }
  }
  return a;
}

PolicyStep PolicyRunner::Impl::step(const float* v, int64_t n, bool target_speed_head) {
  if (!target_speed_head && signed_pedals(ck.model, ck.input.domain)) {
    // throttle - brake[, steer] -> throttle, brake[, steer]
    learned.assign(v, v + n);
    action.resize(static_cast<size_t>(ck.input.action_dim));
    pedals_to_recorded(learned.data(), ck.input.action_dim, action.data());
  } else {
    action.assign(v, v + n);
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
  PolicyStep step;
  if (m.slots == 0 && invariant_inference &&
      remote_policy_run(m.remote_key, frames, m.ck.input.history, m.frame_values, speed, command,
                        previous, m.ck.input.action_dim, &step, &m.action))
    return step;
  return run_batch({PolicyInput{frames, speed, command, previous}}).front();
}

void PolicyRunner::set_batch_slots(int slots) {
  if (slots < 0) throw ConfigError("batch slots must be >= 0");
  impl_->slots = slots;
}
int PolicyRunner::batch_slots() const { return impl_->slots; }

std::vector<PolicyStep> PolicyRunner::run_batch(const std::vector<PolicyInput>& inputs,
                                                std::vector<std::vector<float>>* actions) {
  Impl& m = *impl_;
  const int n = static_cast<int>(inputs.size());
  if (n < 1) throw ConfigError("run_batch: no observation");
  const int chunk = m.slots > 0 ? m.slots : n;  // rows per forward pass
  std::vector<PolicyStep> steps;
  if (actions) actions->clear();
  torch::InferenceMode inference;
  BatchInvariantKernels kernels(invariant_inference);
  for (int first = 0; first < n; first += chunk) {
    const int used = std::min(chunk, n - first);
    m.resize(chunk);
    std::vector<const float*> previous;
    for (int r = 0; r < chunk; ++r) {  // rows past `used`: copies of the chunk's first input
      const PolicyInput& in = inputs[static_cast<size_t>(first + (r < used ? r : 0))];
      m.fill(r, in.frames, in.speed, in.command);
      previous.push_back(in.previous);
    }
    const torch::Tensor a =
        m.act(previous, nullptr, nullptr).detach().to(torch::kCPU).contiguous();
    for (int r = 0; r < used; ++r) {
      steps.push_back(m.step(a.data_ptr<float>() + static_cast<size_t>(r) * a.size(1),
                             a.size(1), target_speed_head()));
      if (actions) actions->push_back(m.action);
    }
  }
  return steps;
}

PolicyStep PolicyRunner::run_with_gradient(const uint8_t* const* frames, double speed,
                                           int command, const float* previous,
                                           FeatureMapGradient& out) {
  Impl& m = *impl_;
  m.resize(1);
  m.fill(0, frames, speed, command);
  torch::AutoGradMode grad_on(true);
  torch::Tensor map;
  torch::Tensor a = m.act({previous}, &map, &out.module);
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
  const torch::Tensor row = a.detach().to(torch::kCPU).contiguous();
  return m.step(row.data_ptr<float>(), row.size(1), target_speed_head());
}

}  // namespace cd
