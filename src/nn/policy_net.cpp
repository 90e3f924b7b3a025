#include "nn/policy_net.hpp"

#include <algorithm>
#include <sstream>
#include <utility>
#include <vector>

#include "core/error.hpp"
#include "nn/kernels.hpp"

namespace cd {

PolicyNetOptions policy_net_options(const ModelSettings& m, int in_channels, int height, int width) {
  PolicyNetOptions o;
  o.in_channels = in_channels;
  o.height = height;
  o.width = width;
  o.backbone = m.backbone;
  o.head = m.head;
  o.action_head = m.action_head;
  o.features = m.features;
  o.dropout = m.dropout;
  return o;
}

namespace nn = torch::nn;

namespace {

constexpr int kBranches = 4;        // follow, left, right, straight (cd::Command)
constexpr int kMeasurementWidth = 128;

int conv_out(int n, int kernel, int stride, int pad) { return (n + 2 * pad - kernel) / stride + 1; }

nn::Conv2d conv(int in, int out, int kernel, int stride, int pad, bool bias) {
  return nn::Conv2d(nn::Conv2dOptions(in, out, kernel).stride(stride).padding(pad).bias(bias));
}

// Linear -> ReLU (-> Dropout) blocks ending in a plain Linear to `out`.
nn::Sequential mlp(const std::vector<int>& widths, int out, double dropout) {
  nn::Sequential s;
  for (size_t i = 0; i + 1 < widths.size(); ++i) {
    s->push_back(nn::Linear(widths[i], widths[i + 1]));
    s->push_back(nn::ReLU());
    if (dropout > 0) s->push_back(nn::Dropout(dropout));
  }
  s->push_back(nn::Linear(widths.back(), out));
  return s;
}

}  // namespace

int action_dim_of(const std::string& action_head) {
  if (action_head == "throttle_brake") return 2;
  if (action_head == "target_speed") return 1;
  throw ConfigError("unknown action head '" + action_head +
                    "' (known: throttle_brake, target_speed)");
}

SmallBackboneImpl::SmallBackboneImpl(int in_channels, int height, int width, int features) {
  if (height < 16 || width < 16)
    throw ConfigError("the small backbone needs BEV frames of at least 16x16 pixels (got " +
                      std::to_string(height) + "x" + std::to_string(width) + ")");
  // Patchify stem and 2x2/stride-2 downsampling (as in ConvNeXt): at batch 1 a 3x3 convolution
  // on these small maps costs about twice as much for the same output size.
  convs = nn::Sequential(
      conv(in_channels, 32, 4, 4, 0, false), nn::BatchNorm2d(32), nn::ReLU(),
      conv(32, 64, 2, 2, 0, false), nn::BatchNorm2d(64), nn::ReLU(),
      conv(64, 128, 2, 2, 0, false), nn::BatchNorm2d(128), nn::ReLU(),
      // Squeezing the channels before the flatten keeps the dense layer small: at batch 1
      // (closed loop) its weights, not the arithmetic, set the inference time.
      conv(128, 32, 1, 1, 0, false), nn::BatchNorm2d(32), nn::ReLU());
  int h = conv_out(conv_out(conv_out(height, 4, 4, 0), 2, 2, 0), 2, 2, 0);
  int w = conv_out(conv_out(conv_out(width, 4, 4, 0), 2, 2, 0), 2, 2, 0);
  fc = nn::Linear(32 * h * w, features);
  register_module("convs", convs);
  register_module("fc", fc);
}

torch::Tensor SmallBackboneImpl::forward(torch::Tensor x) { return features_of(feature_map(x)); }

torch::Tensor SmallBackboneImpl::feature_map(torch::Tensor x) { return sequential_forward(*convs, x); }

torch::Tensor SmallBackboneImpl::features_of(torch::Tensor map) {
  return torch::relu(linear_forward(*fc, map.flatten(1)));
}

BasicBlockImpl::BasicBlockImpl(int in, int out, int stride)
    : conv1(conv(in, out, 3, stride, 1, false)),
      conv2(conv(out, out, 3, 1, 1, false)),
      bn1(out),
      bn2(out) {
  register_module("conv1", conv1);
  register_module("bn1", bn1);
  register_module("conv2", conv2);
  register_module("bn2", bn2);
  if (stride != 1 || in != out) {
    downsample = nn::Sequential(conv(in, out, 1, stride, 0, false), nn::BatchNorm2d(out));
    register_module("downsample", downsample);
  }
}

torch::Tensor BasicBlockImpl::forward(torch::Tensor x) {
  torch::Tensor y = torch::relu(bn1->forward(conv_forward(*conv1, x)));
  y = bn2->forward(conv_forward(*conv2, y));
  return torch::relu(y + (downsample ? sequential_forward(*downsample, x) : x));
}

ResNet34BackboneImpl::ResNet34BackboneImpl(int in_channels, int features) {
  stem = nn::Sequential(conv(in_channels, 64, 7, 2, 3, false), nn::BatchNorm2d(64), nn::ReLU(),
                        nn::MaxPool2d(nn::MaxPool2dOptions(3).stride(2).padding(1)));
  layers = nn::Sequential();
  const int blocks[4] = {3, 4, 6, 3};
  const int widths[4] = {64, 128, 256, 512};
  int in = 64;
  for (int stage = 0; stage < 4; ++stage)
    for (int b = 0; b < blocks[stage]; ++b) {
      layers->push_back(BasicBlock(in, widths[stage], (b == 0 && stage > 0) ? 2 : 1));
      in = widths[stage];
    }
  register_module("stem", stem);
  register_module("layers", layers);
  if (features != 512) {
    proj = nn::Linear(512, features);
    register_module("proj", proj);
  }
}

torch::Tensor ResNet34BackboneImpl::forward(torch::Tensor x) { return features_of(feature_map(x)); }

torch::Tensor ResNet34BackboneImpl::feature_map(torch::Tensor x) {
  return sequential_forward(*layers, sequential_forward(*stem, x));
}

torch::Tensor ResNet34BackboneImpl::features_of(torch::Tensor map) {
  torch::Tensor f = map.mean({2, 3});
  return proj ? torch::relu(linear_forward(*proj, f)) : f;
}

int PolicyNetImpl::action_dim() const {
  return options_.action_dim > 0 ? options_.action_dim : action_dim_of(options_.action_head);
}

PolicyNetImpl::PolicyNetImpl(const PolicyNetOptions& o) : options_(o) {
  const int F = o.features, A = action_dim();
  if (!o.output.empty()) squash_action(torch::zeros({1, A}), o.output);  // a known name
  if (o.backbone == "small") {
    small = SmallBackbone(o.in_channels, o.height, o.width, F);
    register_module("backbone", small);
  } else if (o.backbone == "resnet34") {
    resnet = ResNet34Backbone(o.in_channels, F);
    register_module("backbone", resnet);
  } else {
    throw ConfigError("unknown backbone '" + o.backbone + "' (known: small, resnet34)");
  }
  speed_head = mlp({F, F, F}, 1, 0.0);
  register_module("speed_head", speed_head);
  if (o.head == "linear") {
    linear_head = nn::Linear(F + o.extra_features, A);
    register_module("linear_head", linear_head);
    return;
  }
  if (o.head != "cilrs") throw ConfigError("unknown policy head '" + o.head + "' (known: cilrs, linear)");
  measurement = nn::Sequential(nn::Linear(1, kMeasurementWidth), nn::ReLU(),
                               nn::Linear(kMeasurementWidth, kMeasurementWidth), nn::ReLU());
  fusion = nn::Sequential(nn::Linear(F + kMeasurementWidth + o.extra_features, F), nn::ReLU());
  branches = nn::ModuleList();
  for (int b = 0; b < kBranches; ++b) branches->push_back(mlp({F, F, F}, A, o.dropout));
  register_module("measurement", measurement);
  register_module("fusion", fusion);
  register_module("branches", branches);
}

torch::Tensor squash_action(const torch::Tensor& raw, const std::string& output) {
  if (output == "sigmoid") return torch::sigmoid(raw);
  if (output == "sigmoid_tanh") {
    if (raw.size(1) != 3)
      throw ConfigError("the sigmoid_tanh output squashes (throttle, brake, steer): 3 columns, not " +
                        std::to_string(raw.size(1)));
    return torch::cat({torch::sigmoid(raw.narrow(1, 0, 2)), torch::tanh(raw.narrow(1, 2, 1))}, 1);
  }
  if (output == "softplus") return torch::softplus(raw);
  if (output == "tanh") return torch::tanh(raw);
  if (output == "linear") return raw;
  throw ConfigError("unknown policy output '" + output +
                    "' (known: sigmoid, sigmoid_tanh, softplus, tanh, linear)");
}

torch::Tensor PolicyNetImpl::squash(const torch::Tensor& raw) const {
  if (!options_.output.empty()) return squash_action(raw, options_.output);
  return squash_action(raw, options_.action_head == "throttle_brake" ? "sigmoid" : "softplus");
}

PolicyOutput PolicyNetImpl::forward(const torch::Tensor& image, const torch::Tensor& speed,
                                    const torch::Tensor& command, bool with_speed,
                                    const torch::Tensor& extra) {
  torch::Tensor map = small ? small->feature_map(image) : resnet->feature_map(image);
  torch::Tensor f = small ? small->features_of(map) : resnet->features_of(map);
  PolicyOutput out;
  out.feature_map = map;
  out.feature = f;
  if (with_speed) out.speed = sequential_forward(*speed_head, f);
  std::vector<torch::Tensor> joined = {f};
  if (!linear_head) joined.push_back(sequential_forward(*measurement, speed));
  if (options_.extra_features > 0) {
    if (!extra.defined() || extra.size(1) != options_.extra_features)
      throw Error("policy network: expected an extra feature of width " +
                  std::to_string(options_.extra_features));
    joined.push_back(extra);
  }
  torch::Tensor j = linear_head ? (joined.size() == 1 ? f : torch::cat(joined, 1))
                                : sequential_forward(*fusion, torch::cat(joined, 1));
  out.embedding = j;
  out.action = act(j, command);
  return out;
}

torch::Tensor PolicyNetImpl::act(const torch::Tensor& j, const torch::Tensor& command) {
  if (linear_head) return squash(linear_forward(*linear_head, j));
  const int64_t B = j.size(0);
  auto branch = [&](int64_t b) -> torch::nn::SequentialImpl& {
    return *branches[static_cast<size_t>(b)]->as<nn::Sequential>();
  };
  if (!is_training() && (B == 1 || batch_invariant_kernels())) {
    // Closed loop: each row through its commanded branch only (one row at a time when the
    // kernels are batch-invariant, which is what their linear layers do anyway).
    const torch::Tensor c = command.clamp(0, kBranches - 1).to(torch::kCPU);
    std::vector<torch::Tensor> rows;
    for (int64_t r = 0; r < B; ++r)
      rows.push_back(sequential_forward(branch(c[r].item<int64_t>()), j.narrow(0, r, 1)));
    return squash(B == 1 ? rows.front() : torch::cat(rows, 0));
  }
  std::vector<torch::Tensor> all;
  for (int b = 0; b < kBranches; ++b) all.push_back(sequential_forward(branch(b), j));
  torch::Tensor stacked = torch::stack(all, 1);  // B x 4 x A
  torch::Tensor index =
      command.clamp(0, kBranches - 1).view({B, 1, 1}).expand({B, 1, stacked.size(2)});
  return squash(stacked.gather(1, index).squeeze(1));
}

std::string save_module_bytes(nn::Module& module) {
  torch::serialize::OutputArchive archive;
  module.save(archive);
  std::ostringstream os;
  archive.save_to(os);
  return os.str();
}

std::string save_optimizer_bytes(const torch::optim::Optimizer& opt) {
  torch::serialize::OutputArchive archive;
  opt.save(archive);
  std::ostringstream os;
  archive.save_to(os);
  return os.str();
}

void load_optimizer_bytes(torch::optim::Optimizer& opt, const std::string& bytes,
                          const torch::Device& device, const std::string& what,
                          const std::string& hint) {
  try {
    std::istringstream is(bytes);
    torch::serialize::InputArchive archive;
    archive.load_from(is, device);
    opt.load(archive);
  } catch (const c10::Error&) {
    throw DataError(what + " does not fit the network" + hint);
  }
}

void load_module_bytes(nn::Module& module, const std::string& bytes, const torch::Device& device,
                       const std::string& what) {
  // torch's Module::load replaces each tensor whatever its shape: the shapes are checked here.
  std::vector<std::pair<std::string, std::vector<int64_t>>> shapes;
  for (const auto& p : module.named_parameters()) shapes.emplace_back(p.key(), p.value().sizes().vec());
  for (const auto& b : module.named_buffers()) shapes.emplace_back(b.key(), b.value().sizes().vec());
  const std::string hint = "; was it written by another version or with other model settings?";
  try {
    std::istringstream is(bytes);
    torch::serialize::InputArchive archive;
    archive.load_from(is, device);
    module.load(archive);
  } catch (const c10::Error& e) {
    std::string msg = e.what_without_backtrace();
    throw DataError(what + " does not fit this network (" + msg.substr(0, msg.find('\n')) + ")" +
                    hint);
  }
  size_t i = 0;
  auto check = [&](const std::string& key, const torch::Tensor& t) {
    if (i >= shapes.size() || shapes[i].first != key || shapes[i].second != t.sizes().vec())
      throw DataError(what + " does not fit this network (tensor '" + key + "' has another shape)" +
                      hint);
    ++i;
  };
  for (const auto& p : module.named_parameters()) check(p.key(), p.value());
  for (const auto& b : module.named_buffers()) check(b.key(), b.value());
}

}  // namespace cd
