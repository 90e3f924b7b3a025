// The policy network (nn/policy_net): shapes and ranges of both heads, the save/load round
// trip, the ResNet34 backbone.
#include "nn/policy_net.hpp"

#include <gtest/gtest.h>

#include <string>
#include <vector>

#include <torch/torch.h>

#include "core/error.hpp"

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
