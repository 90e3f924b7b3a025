#include "nn/policy_nets.hpp"

#include "core/error.hpp"
#include "nn/kernels.hpp"

namespace cd {

namespace nn = torch::nn;

namespace {

nn::Sequential leaky_mlp(int in, int hidden, int out) {
  const auto leaky = nn::LeakyReLUOptions().negative_slope(0.2);
  return nn::Sequential(nn::Linear(in, hidden), nn::LeakyReLU(leaky), nn::Linear(hidden, hidden),
                        nn::LeakyReLU(leaky), nn::Linear(hidden, out));
}

}  // namespace

PolicyNetsLayout policy_layout(const std::string& method, const ModelSettings& model,
                               const ResidualSettings& residual, const FcaSettings& fca,
                               int frame_channels, int height, int width, int action_dim,
                               const std::string& domain) {
  PolicyNetsLayout l;
  l.method = method;
  const bool pedals = signed_pedals(model, domain);
  if (pedals) action_dim -= 1;  // throttle - brake[, steer]
  l.action_dim = action_dim;
  l.history = model.history;
  if (model.action_head == "target_speed" && domain == "mujoco")
    throw ConfigError("MuJoCo-Image data has no speed: set model.action_head = \"throttle_brake\" "
                      "(the recorded action)");
  l.action_output = model.action_head == "target_speed" ? "softplus"
                    : domain == "mujoco" || pedals      ? "tanh"
                    : action_dim == 3                   ? "sigmoid_tanh"
                                                        : "sigmoid";
  l.policy = policy_net_options(model, model.history * frame_channels, height, width);
  l.policy.action_dim = model.action_head == "target_speed" ? 1 : action_dim;
  l.policy.output = l.action_output;
  if (method == "fca") {
    l.has_adversary = true;
    l.adversary_hidden = fca.hidden;
  }
  if (method != "residual") return l;

  if (model.action_head != "throttle_brake")
    throw ConfigError("residual learns the recorded action: set model.action_head = "
                      "\"throttle_brake\"");
  if (model.history < 2)
    throw ConfigError("residual's memory module needs a frame history: model.history >= 2");
  l.has_memory = true;
  l.memory_target = residual.memory_target;
  l.memory = policy_net_options(model, model.history * frame_channels, height, width);
  if (residual.memory_target == "residual") {
    l.memory_heads = residual.branches;
    l.memory.action_dim = action_dim * residual.branches;
    l.memory.output = "linear";  // differences of actions
  } else {
    if (residual.branches != 1)
      throw ConfigError("residual.branches > 1 needs residual.memory_target = \"residual\"");
    l.memory.action_dim = action_dim;
    l.memory.output = l.action_output;  // it predicts actions
  }
  if (residual.policy == "residual_controller" && residual.memory_target != "residual")
    throw ConfigError("residual.policy = \"residual_controller\" adds the memory's residual to "
                      "a_{t-1}: it needs residual.memory_target = \"residual\"");
  if (residual.policy == "stream") {
    l.policy_sees_history = residual.policy_input == "history";
    l.policy.in_channels = (l.policy_sees_history ? model.history : 1) * frame_channels;
    l.policy.extra_features = model.features;
  } else {
    if (residual.policy_input != "current")
      throw ConfigError("residual.policy_input applies to the policy stream "
                        "(residual.policy = \"stream\") only");
    l.has_policy = false;
    l.has_controller = residual.policy == "learned_controller";
  }
  return l;
}

PolicyNets::PolicyNets(const PolicyNetsLayout& l) : layout(l) {
  holder_ = std::make_shared<nn::Module>();
  if (l.has_policy) policy = PolicyNet(l.policy);
  if (l.has_memory) memory = PolicyNet(l.memory);
  if (l.has_adversary)
    adversary = leaky_mlp(l.policy.features + l.action_dim, l.adversary_hidden, l.action_dim);
  if (l.has_controller) {
    const int F = l.memory.features;
    controller = nn::Sequential(nn::Linear(F, F), nn::ReLU(), nn::Linear(F, F), nn::ReLU(),
                                nn::Linear(F, l.action_dim));
  }
  if (policy) holder_->register_module("policy", policy);
  if (memory) holder_->register_module("memory", memory);
  if (adversary) holder_->register_module("adversary", adversary);
  if (controller) holder_->register_module("controller", controller);
}

std::vector<torch::Tensor> PolicyNets::parameters() { return holder_->parameters(); }

std::vector<torch::Tensor> PolicyNets::adversary_parameters() {
  return adversary ? adversary->parameters() : std::vector<torch::Tensor>{};
}

void PolicyNets::set_training(bool on) { holder_->train(on); }

void PolicyNets::to(const torch::Device& device) { holder_->to(device); }

std::string PolicyNets::save_bytes() {
  return bare() ? save_module_bytes(*policy) : save_module_bytes(*holder_);
}

void PolicyNets::load_bytes(const std::string& bytes, const torch::Device& device,
                            const std::string& what) {
  if (bare())
    load_module_bytes(*policy, bytes, device, what);
  else
    load_module_bytes(*holder_, bytes, device, what);
}

torch::Tensor PolicyNets::squash(const torch::Tensor& raw) const {
  return squash_action(raw, layout.action_output);
}

torch::Tensor PolicyNets::control(const torch::Tensor& memory_feature) {
  return squash(sequential_forward(*controller, memory_feature));
}

}  // namespace cd
