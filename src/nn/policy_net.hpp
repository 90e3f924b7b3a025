#pragma once
// The behaviour-cloning policy of bc-so / bc-oh: the CILRS architecture of seed 001 (fig. 5).
//
//   image (K*C planes of 0/1, oldest frame first) -> backbone -> feature f
//   f -> 3-layer MLP -> predicted ego speed (auxiliary "speed regularisation" head)
//   speed input (zeros in the POMDP setting) -> 2-layer MLP -> m
//   [f, m] -> fusion layer -> j
//   j -> one of 4 branches chosen by the command (follow, left, right, straight) -> action
// With head "linear" (seed 001's MuJoCo model, fig. 10): [f, extra] -> one linear layer ->
// action; no speed input, fusion layer or branches (the speed head stays, unused when its
// loss weight is 0); the embedding is [f, extra].
//
// Action heads: throttle_brake -> 2 sigmoid outputs in [0,1]; target_speed -> 1 softplus
// output in m/s (never negative, and unlike ReLU it keeps a gradient at a standstill).
// Backbones: "small", a CPU-sized CNN (see SmallBackbone), and "resnet34", a real ResNet34
// (BasicBlocks 3-4-6-3) with a first convolution taking K*C channels, trained from scratch:
// no ImageNet weights are available here (the seed starts from pretrained ones).
//
// This header includes torch: include it only from the .cpp files that run the network.
#include <string>

#include <torch/torch.h>

#include "nn/model_settings.hpp"

namespace cd {

struct PolicyNetOptions {
  int in_channels = 8;  // K * C
  int height = 64, width = 64;
  std::string backbone = "small";              // small | resnet34
  std::string head = "cilrs";                  // cilrs | linear (ModelSettings::head)
  std::string action_head = "throttle_brake";  // throttle_brake | target_speed
  int features = 256;
  double dropout = 0.2;
  // The output: 0 / "" take the action head's (2 sigmoid or 1 softplus outputs). Seed 001's
  // memory module learns differences of actions: action_dim = A * branches, output "linear".
  int action_dim = 0;
  std::string output;  // "" | an output of squash_action
  // Width of a feature given beside the image and joined before the fusion layer (residual:
  // the memory module's detached backbone feature); 0: none.
  int extra_features = 0;
};

// The network [model] describes, for inputs of in_channels x height x width (one mapping for
// the trainer and the closed-loop runner).
PolicyNetOptions policy_net_options(const ModelSettings& m, int in_channels, int height, int width);

// Width of the action output of a head name: 2 (throttle, brake) or 1 (target speed).
int action_dim_of(const std::string& action_head);

// The squash of an action output (B x A), by name: "sigmoid" (throttle, brake in [0,1]),
// "sigmoid_tanh" (driving with steer: sigmoid on throttle and brake, tanh on the steer column
// after them, in [-1,1]), "tanh" (MuJoCo-Image's actions in [-1,1]), "softplus" (a target
// speed, never negative), "linear" (none). ConfigError for another name.
torch::Tensor squash_action(const torch::Tensor& raw, const std::string& output);

struct PolicyOutput {
  torch::Tensor action;     // B x action_dim
  torch::Tensor speed;      // B x 1, predicted ego speed (m/s); undefined when not asked for
  torch::Tensor feature;    // B x features: the backbone's output f
  torch::Tensor embedding;  // B x features: the fusion output j the branches read ("linear": [f, extra])
  // B x C x h x w: the backbone's last convolutional feature map, the one `feature` is
  // computed from (what Grad-CAM weighs; diagnostics/attention).
  torch::Tensor feature_map;
};

// Five stages, sized for 64x64 inputs on a CPU: a 4x4/stride-4 patch convolution (the input
// has K*C planes, so a first layer at full resolution would cost most of the budget), two
// 2x2/stride-2 convolutions (64 -> 16 -> 8 -> 4 pixels), a 1x1 squeeze to 32 channels, and a
// fully connected layer to `features`; BatchNorm + ReLU after every convolution. About
// 1 M multiply-adds per stacked 8-plane frame plus 1.2 M for the rest of the backbone.
struct SmallBackboneImpl : torch::nn::Module {
  SmallBackboneImpl(int in_channels, int height, int width, int features);
  // forward(x) = features_of(feature_map(x)), the same operations in the same order.
  torch::Tensor forward(torch::Tensor x);
  // The output of the last conv block (after its ReLU), before the flatten: B x 32 x h x w.
  torch::Tensor feature_map(torch::Tensor x);
  // The rest of the backbone: flatten, dense layer, ReLU.
  torch::Tensor features_of(torch::Tensor map);

  torch::nn::Sequential convs{nullptr};
  torch::nn::Linear fc{nullptr};
};
TORCH_MODULE(SmallBackbone);

struct BasicBlockImpl : torch::nn::Module {
  BasicBlockImpl(int in, int out, int stride);
  torch::Tensor forward(torch::Tensor x);

  torch::nn::Conv2d conv1{nullptr}, conv2{nullptr};
  torch::nn::BatchNorm2d bn1{nullptr}, bn2{nullptr};
  torch::nn::Sequential downsample{nullptr};  // 1x1 conv + BN when the shape changes
};
TORCH_MODULE(BasicBlock);

// ResNet34 (He et al. 2016) up to the global average pool, then a linear map to `features`
// when that is not 512.
struct ResNet34BackboneImpl : torch::nn::Module {
  ResNet34BackboneImpl(int in_channels, int features);
  // forward(x) = features_of(feature_map(x)), the same operations in the same order.
  torch::Tensor forward(torch::Tensor x);
  // The last stage's output (after its last block): B x 512 x h x w.
  torch::Tensor feature_map(torch::Tensor x);
  // The rest: global average pool (and the projection to `features` when there is one).
  torch::Tensor features_of(torch::Tensor map);

  torch::nn::Sequential stem{nullptr}, layers{nullptr};
  torch::nn::Linear proj{nullptr};
};
TORCH_MODULE(ResNet34Backbone);

struct PolicyNetImpl : torch::nn::Module {
  explicit PolicyNetImpl(const PolicyNetOptions& options);

  // image: B x K*C x H x W float; speed: B x 1 float (m/s, zeros in the POMDP setting);
  // command: B int64 in [0, 3]. with_speed: also run the auxiliary speed head. extra:
  // B x extra_features (required when the options have extra features).
  PolicyOutput forward(const torch::Tensor& image, const torch::Tensor& speed,
                       const torch::Tensor& command, bool with_speed = true,
                       const torch::Tensor& extra = {});
  // The commanded branch's action from an embedding j (what forward ends with).
  torch::Tensor act(const torch::Tensor& embedding, const torch::Tensor& command);
  int action_dim() const;

  const PolicyNetOptions& options() const { return options_; }

  // Exactly one backbone is set, registered as "backbone".
  SmallBackbone small{nullptr};
  ResNet34Backbone resnet{nullptr};
  torch::nn::Sequential speed_head{nullptr}, measurement{nullptr}, fusion{nullptr};
  torch::nn::ModuleList branches{nullptr};
  torch::nn::Linear linear_head{nullptr};  // head "linear" only

 private:
  torch::Tensor squash(const torch::Tensor& raw) const;  // the head's output nonlinearity
  PolicyNetOptions options_;
};
TORCH_MODULE(PolicyNet);

// The module's parameters and buffers as the bytes of torch::save, and back. Throws
// DataError (naming `what`) when the bytes do not fit the network.
std::string save_module_bytes(torch::nn::Module& module);
void load_module_bytes(torch::nn::Module& module, const std::string& bytes,
                       const torch::Device& device, const std::string& what);
// The same for an optimiser's state (Adam's moments and step counts).
std::string save_optimizer_bytes(const torch::optim::Optimizer& opt);
void load_optimizer_bytes(torch::optim::Optimizer& opt, const std::string& bytes,
                          const torch::Device& device, const std::string& what,
                          const std::string& hint = "");

}  // namespace cd
