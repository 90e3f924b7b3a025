// The policy network (nn/policy_net): shapes and ranges of both heads, the action squash by
// name and by layout, the save/load round trip, the ResNet34 backbone.
#include "nn/policy_net.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include <torch/torch.h>

#include "core/error.hpp"
#include "nn/policy_nets.hpp"

namespace cd {
namespace {

struct TorchThreads {
  TorchThreads() { torch::set_num_threads(1); }
} const kOneThread;

torch::Tensor binary_input(int64_t b, int64_t c, int64_t h, int64_t w) {
  return (torch::rand({b, c, h, w}) > 0.7).to(torch::kFloat32);
}

TEST(PolicyNet, ShapesAndRangesOfBothHeads) {
  torch::manual_seed(1);
  PolicyNetOptions o;
  o.in_channels = 16;
  o.height = 32;
  o.width = 32;
  o.features = 32;
  PolicyNet tb(o);
  tb->eval();
  torch::Tensor x = binary_input(5, 16, 32, 32), v = torch::zeros({5, 1});
  torch::Tensor cmd = torch::tensor({0, 1, 2, 3, 1}, torch::kInt64);
  PolicyOutput out = tb->forward(x, v, cmd);
  EXPECT_EQ(out.action.sizes(), (std::vector<int64_t>{5, 2}));
  EXPECT_EQ(out.speed.sizes(), (std::vector<int64_t>{5, 1}));
  EXPECT_GE(out.action.min().item<float>(), 0.0f);
  EXPECT_LE(out.action.max().item<float>(), 1.0f);
  // The batch path (all branches, gathered) and the closed-loop path (one branch) agree.
  for (int i = 0; i < 5; ++i) {
    PolicyOutput one = tb->forward(x.narrow(0, i, 1), v.narrow(0, i, 1), cmd.narrow(0, i, 1), false);
    EXPECT_TRUE(torch::allclose(one.action, out.action.narrow(0, i, 1), 1e-5, 1e-6)) << i;
    EXPECT_FALSE(one.speed.defined());
  }
  // Commands select different branches.
  PolicyOutput a = tb->forward(x.narrow(0, 0, 1), v.narrow(0, 0, 1), torch::tensor({0}, torch::kInt64));
  PolicyOutput b = tb->forward(x.narrow(0, 0, 1), v.narrow(0, 0, 1), torch::tensor({2}, torch::kInt64));
  EXPECT_FALSE(torch::equal(a.action, b.action));

  o.action_head = "target_speed";
  PolicyNet ts(o);
  ts->eval();
  PolicyOutput s = ts->forward(x, v, cmd);
  EXPECT_EQ(s.action.sizes(), (std::vector<int64_t>{5, 1}));
  EXPECT_GE(s.action.min().item<float>(), 0.0f) << "target speed is never negative";
}

// Seed 001's MuJoCo model (fig. 10): the backbone's feature, joined with an extra feature, read
// by one linear layer; no speed input, fusion or branches. Checked against tanh(W [f, e] + b)
// computed from the layer's own parameters.
TEST(PolicyNet, LinearHeadIsOneLayerOnTheFeature) {
  torch::manual_seed(2);
  PolicyNetOptions o;
  o.in_channels = 6;
  o.height = o.width = 32;
  o.features = 20;
  o.head = "linear";
  o.action_dim = 3;
  o.output = "tanh";
  o.extra_features = 4;
  PolicyNet net(o);
  net->eval();
  EXPECT_FALSE(net->measurement) << "no speed input";
  EXPECT_FALSE(net->fusion);
  EXPECT_FALSE(net->branches);
  ASSERT_TRUE(net->linear_head);
  torch::Tensor x = torch::rand({5, 6, 32, 32}), e = torch::randn({5, 4});
  torch::Tensor speed = torch::randn({5, 1}), cmd = torch::tensor({0, 1, 2, 3, 0}, torch::kInt64);
  PolicyOutput out = net->forward(x, speed, cmd, false, e);
  ASSERT_EQ(out.action.sizes(), (std::vector<int64_t>{5, 3}));
  torch::Tensor joined = torch::cat({out.feature, e}, 1);
  EXPECT_TRUE(torch::equal(out.embedding, joined));
  torch::Tensor by_hand =
      torch::tanh(torch::matmul(joined, net->linear_head->weight.t()) + net->linear_head->bias);
  EXPECT_TRUE(torch::allclose(out.action, by_hand, 1e-5, 1e-6));
  // The command and the speed are not read.
  PolicyOutput other = net->forward(x, torch::zeros({5, 1}), torch::zeros({5}, torch::kInt64), false, e);
  EXPECT_TRUE(torch::equal(out.action, other.action));
  // Parameters: the backbone, the (unused) speed head and the one layer.
  for (const auto& p : net->named_parameters())
    EXPECT_TRUE(p.key().rfind("backbone.", 0) == 0 || p.key().rfind("speed_head.", 0) == 0 ||
                p.key().rfind("linear_head.", 0) == 0)
        << p.key();
  o.head = "mlp";
  EXPECT_THROW(PolicyNet{o}, ConfigError);
}

// The squash by name, against torch's own functions on a hand-made output: steer (the third
// driving column) and MuJoCo-Image actions keep their sign.
TEST(PolicyNet, SquashActionByName) {
  const torch::Tensor raw = torch::tensor({{-3.0f, 0.0f, -2.0f}, {4.0f, 1.0f, 0.5f}});
  const torch::Tensor st = squash_action(raw, "sigmoid_tanh");
  for (int i = 0; i < 2; ++i) {
    for (int k = 0; k < 2; ++k)
      EXPECT_FLOAT_EQ(st[i][k].item<float>(), 1.0f / (1.0f + std::exp(-raw[i][k].item<float>())));
    EXPECT_FLOAT_EQ(st[i][2].item<float>(), std::tanh(raw[i][2].item<float>()));
  }
  EXPECT_LT(st[0][2].item<float>(), -0.9f) << "a right turn is an output";
  EXPECT_TRUE(torch::equal(squash_action(raw, "linear"), raw));
  EXPECT_TRUE(torch::allclose(squash_action(raw, "tanh"), torch::tanh(raw)));
  EXPECT_TRUE(torch::allclose(squash_action(raw, "softplus"), torch::softplus(raw)));
  EXPECT_THROW(squash_action(raw.narrow(1, 0, 2), "sigmoid_tanh"), ConfigError);
  EXPECT_THROW(squash_action(raw, "relu"), ConfigError);
}

// The networks policy_layout builds squash by the data's actions: throttle and brake in [0,1]
// with a steer in [-1,1] after them (a free-steering ego's data), every column in [-1,1] for
// MuJoCo-Image, for the policy and for residual's action-predicting memory module. A large
// negative bias on the last layer must come out as a negative steer / action.
TEST(PolicyNet, LayoutsSquashSteerAndMujocoActionsSigned) {
  torch::manual_seed(3);
  ModelSettings model;
  model.features = 16;
  model.history = 2;
  model.pedals = "two";  // as recorded (signed pedals: test_pedals.cpp)
  ResidualSettings residual;
  residual.memory_target = "action";
  residual.branches = 1;
  residual.policy = "stream";
  const FcaSettings fca;
  struct Case { const char* domain; int action_dim; const char* output; };
  for (const Case& c : {Case{"driving", 2, "sigmoid"}, Case{"driving", 3, "sigmoid_tanh"},
                        Case{"mujoco", 3, "tanh"}}) {
    SCOPED_TRACE(c.domain + std::string(" x") + std::to_string(c.action_dim));
    const PolicyNetsLayout l =
        policy_layout("residual", model, residual, fca, 4, 32, 32, c.action_dim, c.domain);
    EXPECT_EQ(l.action_output, c.output);
    EXPECT_EQ(l.policy.output, c.output);
    EXPECT_EQ(l.memory.output, c.output);
    PolicyNets nets(l);
    nets.set_training(false);
    torch::NoGradGuard no_grad;
    for (PolicyNet* net : {&nets.policy, &nets.memory}) {
      for (auto& p : (*net)->named_parameters())
        if (p.key().rfind("branches.", 0) == 0 && p.key().find("bias") != std::string::npos &&
            p.value().size(0) == c.action_dim)
          p.value().fill_(-30.0f);
      const int channels = (*net)->options().in_channels;
      const torch::Tensor extra = (*net)->options().extra_features > 0
                                      ? torch::zeros({2, (*net)->options().extra_features})
                                      : torch::Tensor();
      const torch::Tensor a = (*net)->forward(binary_input(2, channels, 32, 32), torch::zeros({2, 1}),
                                             torch::tensor({0, 2}, torch::kInt64), false, extra)
                                  .action;
      ASSERT_EQ(a.size(1), c.action_dim);
      const torch::Tensor last = a.narrow(1, c.action_dim - 1, 1);
      if (std::string(c.output) == "sigmoid")
        EXPECT_GE(last.min().item<float>(), 0.0f);
      else
        EXPECT_LT(last.max().item<float>(), -0.99f) << a;
      EXPECT_GE(a.min().item<float>(), std::string(c.output) == "sigmoid" ? 0.0f : -1.0f);
      EXPECT_LE(a.max().item<float>(), 1.0f);
    }
  }
}

TEST(PolicyNet, SaveLoadRoundTripGivesIdenticalOutputs) {
  torch::manual_seed(2);
  PolicyNetOptions o;
  o.in_channels = 8;
  o.height = 32;
  o.width = 32;
  o.features = 32;
  PolicyNet a(o);
  // Move the BatchNorm statistics away from their initial values, so buffers must travel too.
  a->train();
  for (int i = 0; i < 3; ++i)
    a->forward(binary_input(4, 8, 32, 32), torch::rand({4, 1}), torch::zeros({4}, torch::kInt64));
  a->eval();
  const std::string bytes = save_module_bytes(*a);
  torch::manual_seed(99);
  PolicyNet b(o);
  torch::Tensor x = binary_input(3, 8, 32, 32), v = torch::rand({3, 1});
  torch::Tensor cmd = torch::tensor({3, 0, 1}, torch::kInt64);
  b->eval();
  ASSERT_FALSE(torch::equal(a->forward(x, v, cmd).action, b->forward(x, v, cmd).action));
  load_module_bytes(*b, bytes, torch::kCPU, "test bytes");
  b->eval();
  PolicyOutput pa = a->forward(x, v, cmd), pb = b->forward(x, v, cmd);
  EXPECT_TRUE(torch::equal(pa.action, pb.action));
  EXPECT_TRUE(torch::equal(pa.speed, pb.speed));
  EXPECT_EQ(save_module_bytes(*b), bytes) << "saving again gives the same bytes";

  // Bytes of another network are refused with a DataError, not a crash.
  o.features = 16;
  PolicyNet c(o);
  EXPECT_THROW(load_module_bytes(*c, bytes, torch::kCPU, "test bytes"), DataError);
}

TEST(PolicyNet, ResNet34TakesStackedFrames) {
  torch::manual_seed(3);
  PolicyNetOptions o;
  o.in_channels = 24;
  o.height = 64;
  o.width = 64;
  o.backbone = "resnet34";
  o.features = 64;
  PolicyNet net(o);
  net->eval();
  long block_convs = 0, convs = 0;
  for (const auto& p : net->named_parameters()) {
    if (p.value().dim() != 4) continue;
    ++convs;
    if (p.key().find(".conv") != std::string::npos) ++block_convs;
  }
  EXPECT_EQ(block_convs, 2 * (3 + 4 + 6 + 3)) << "two convolutions per BasicBlock, 3-4-6-3";
  EXPECT_EQ(convs, 1 + 2 * (3 + 4 + 6 + 3) + 3) << "stem, blocks, 3 downsampling shortcuts";
  torch::NoGradGuard no_grad;
  PolicyOutput out = net->forward(binary_input(2, 24, 64, 64), torch::zeros({2, 1}),
                                  torch::tensor({0, 3}, torch::kInt64));
  EXPECT_EQ(out.action.sizes(), (std::vector<int64_t>{2, 2}));
}

}  // namespace
}  // namespace cd
