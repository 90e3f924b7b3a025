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
