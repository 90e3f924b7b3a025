// Seed 001's methods (methods/residual, fca, keyframe, hd and the family trainer): each loss on
// a hand-made batch against a hand computation, the gradient paths, the history-dropout rate,
// and every method trained twice in-process on hand-made episodes (same seed, same bytes; a
// resumed run equals an uninterrupted one), then driving as an agent.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <vector>

#include <torch/torch.h>

#include "../support/fake_episodes.hpp"
#include "core/error.hpp"
#include "datasets/dataset.hpp"
#include "datasets/episode_set.hpp"
#include "inference/policy_runner.hpp"
#include "methods/method.hpp"
#include "methods/policy_family.hpp"
#include "runs/checkpoint.hpp"

namespace cd {
namespace {

using test::TempDir;

struct TorchThreads {
  TorchThreads() { torch::set_num_threads(1); }
} const kOneThread;

torch::Tensor t2(std::vector<std::vector<float>> rows) {
  const int64_t n = static_cast<int64_t>(rows.size()), a = static_cast<int64_t>(rows[0].size());
  torch::Tensor t = torch::empty({n, a});
  for (int64_t i = 0; i < n; ++i)
    for (int64_t j = 0; j < a; ++j) t[i][j] = rows[i][j];
  return t;
}

// ---- residual -----------------------------------------------------------------------------

TEST(Residual, MemoryTargetsAreActionDifferences) {
  // Two samples, A = 2, L = 2 previous actions (a_{t-1} first).
  torch::Tensor action = t2({{0.5f, 0.1f}, {0.0f, 1.0f}});
  torch::Tensor previous = torch::tensor({0.2f, 0.3f, 0.1f, 0.0f, 0.4f, 0.6f, 1.0f, 0.0f}).view({2, 2, 2});
  torch::Tensor r1 = memory_targets("residual", action, previous, 1);
  EXPECT_TRUE(torch::allclose(r1, t2({{0.3f, -0.2f}, {-0.4f, 0.4f}})));
  torch::Tensor r2 = memory_targets("residual", action, previous, 2);
  EXPECT_TRUE(torch::allclose(r2, t2({{0.3f, -0.2f, 0.4f, 0.1f}, {-0.4f, 0.4f, -1.0f, 1.0f}})));
  EXPECT_TRUE(torch::equal(memory_targets("action", action, previous, 1), action));
  EXPECT_TRUE(torch::equal(memory_targets("previous", action, previous, 1), previous.select(1, 0)));
}

TEST(Residual, PreviousActionsAreRecordedOnesFromTheEpisodeStart) {
  TempDir dir("cd-s001");
  test::write_fake_folder(dir / "data", 2, {.frames = 12, .channels = 2, .height = 16, .width = 16});
  DatasetOptions o;
  o.history = 2;
  o.stride = 1;
  o.action_lags = 3;
  o.val_fraction = 0;
  Dataset data(load_episode_set(dir / "data"), o);
  // History 2 needs t >= 1, three previous actions need t >= 3: no padded action.
  EXPECT_EQ(data.first_step(), 3);
  ASSERT_EQ(data.train().size(), 2u * (12 - 3));
  EXPECT_EQ(data.train().front().t, 3);
  std::vector<float> img(data.image_values()), act(2), prev(6);
  float sp = 0, lab = 0;
  int64_t cmd = 0;
  const SampleRef s = data.train()[10];  // episode 1, t = 4
  data.fill(s, {img.data(), &sp, &cmd, act.data(), &lab, prev.data()});
  // fake actions: (t / 1000, episode / 100).
  EXPECT_FLOAT_EQ(act[0], s.t / 1000.0f);
  for (int i = 1; i <= 3; ++i) {
    EXPECT_FLOAT_EQ(prev[2 * (i - 1)], (s.t - i) / 1000.0f) << i;
    EXPECT_FLOAT_EQ(prev[2 * (i - 1) + 1], s.episode / 100.0f) << i;
  }
}

Settings tiny_settings() {
  Settings s;
  s.model.features = 16;
  s.model.history = 3;
  s.model.history_stride = 1;
  s.model.dropout = 0;
  s.model.pedals = "two";  // the mechanics below by two pedals (signed: test_pedals.cpp)
  s.train.batch_size = 8;
  s.train.threads = 1;
  s.train.device = "cpu";  // same bytes are the CPU's (a GPU machine would resolve auto to CUDA)
  s.train.lr = 1e-3;
  s.ego.lateral = "route";  // the hand-made episodes hold (throttle, brake): no steer
  return s;
}

// A batch of n random samples: 3 frames of 2 channels, 16 x 16.
PolicyBatch random_batch(int64_t n, int lags) {
  PolicyBatch b;
  b.n = n;
  b.image = (torch::rand({n, 6, 16, 16}) > 0.7).to(torch::kFloat32);
  b.speed_in = torch::zeros({n, 1});
  b.command = torch::randint(0, 4, {n}, torch::kInt64);
  b.action = torch::rand({n, 2});
  b.speed_label = torch::rand({n, 1}) * 5;
  if (lags > 0) b.previous = torch::rand({n, lags, 2});
  b.rows = torch::arange(n, torch::kInt64);
  return b;
}

TEST(Residual, NoGradientOfThePolicyLossReachesTheMemoryModule) {
  torch::manual_seed(1);
  Settings s = tiny_settings();
  PolicyNets nets(policy_layout("residual", s.model, s.residual, s.fca, 2, 16, 16, 2));
  ASSERT_TRUE(nets.memory && nets.policy);
  EXPECT_EQ(nets.layout.policy.in_channels, 2);  // the current frame only
  PolicyBatch b = random_batch(8, 1);
  ResidualLosses l = residual_losses(nets, b, s, 2);
  l.act.backward();
  for (const auto& p : nets.memory->named_parameters())
    EXPECT_FALSE(p.value().grad().defined() && p.value().grad().abs().sum().item<double>() > 0)
        << p.key();
  double policy_grad = 0;
  for (const auto& p : nets.policy->parameters())
    if (p.grad().defined()) policy_grad += p.grad().abs().sum().item<double>();
  EXPECT_GT(policy_grad, 0);
  // And the memory loss trains the memory module only.
  clear_grads(nets.parameters());
  residual_losses(nets, b, s, 2).memory.backward();
  for (const auto& p : nets.policy->named_parameters()) EXPECT_FALSE(p.value().grad().defined()) << p.key();
}

TEST(Residual, LossIsL1OfTheResidualPlusSpeedHead) {
  // With the speed head weighted 0, the memory loss is mean |M(o) - (a_t - a_{t-1})|.
  torch::manual_seed(2);
  Settings s = tiny_settings();
  s.model.speed_loss_weight = 0;
  PolicyNets nets(policy_layout("residual", s.model, s.residual, s.fca, 2, 16, 16, 2));
  nets.set_training(false);
  PolicyBatch b = random_batch(5, 1);
  torch::NoGradGuard ng;
  ResidualLosses l = residual_losses(nets, b, s, 2);
  torch::Tensor m = nets.memory->forward(b.image, b.speed_in, b.command, false).action;
  torch::Tensor want = (m - (b.action - b.previous.select(1, 0))).abs().mean();
  EXPECT_NEAR(l.memory.item<double>(), want.item<double>(), 1e-6);
}

TEST(Residual, AblationLayouts) {
  Settings s = tiny_settings();
  auto layout = [&] { return policy_layout("residual", s.model, s.residual, s.fca, 2, 16, 16, 2); };
  s.residual.branches = 3;
  EXPECT_EQ(layout().memory.action_dim, 6);
  s.residual.memory_target = "action";
  EXPECT_THROW(layout(), ConfigError);  // branches are residual heads
  s.residual.branches = 1;
  EXPECT_EQ(layout().memory.action_dim, 2);
  s.residual.policy = "residual_controller";
  EXPECT_THROW(layout(), ConfigError);  // adds a residual: needs the residual target
  s.residual.memory_target = "residual";
  EXPECT_FALSE(layout().has_policy);
  EXPECT_FALSE(layout().has_controller);
  s.residual.policy = "learned_controller";
  EXPECT_TRUE(layout().has_controller);
  s.residual.policy = "stream";
  s.residual.policy_input = "history";
  EXPECT_EQ(layout().policy.in_channels, 6);
  s.model.history = 1;
  EXPECT_THROW(layout(), ConfigError);
}

// ---- keyframe -----------------------------------------------------------------------------

TEST(Keyframe, ThresholdWeightsMatchASortedCount) {
  torch::manual_seed(3);
  torch::Tensor ape = torch::rand({40, 2});
  torch::Tensor w = keyframe_threshold_weights(ape, 0.1, 5.0);
  for (int c = 0; c < 2; ++c) {
    std::vector<float> col(40);
    for (int i = 0; i < 40; ++i) col[i] = ape[i][c].item<float>();
    std::vector<float> sorted = col;
    std::sort(sorted.begin(), sorted.end(), std::greater<float>());
    const float threshold = sorted[3];  // the 4th largest: ceil(0.1 * 40) = 4 samples
    int top = 0;
    for (int i = 0; i < 40; ++i) {
      const float want = col[i] >= threshold ? 5.0f : 1.0f;
      EXPECT_EQ(w[i][c].item<float>(), want) << i << " " << c;
      top += want == 5.0f;
    }
    EXPECT_EQ(top, 4);
  }
}

TEST(Keyframe, SoftmaxWeightsByHand) {
  torch::Tensor ape = t2({{0.0f}, {1.0f}, {2.0f}});
  torch::Tensor w = keyframe_softmax_weights(ape, 0.5);
  const double e0 = 1, e1 = std::exp(2.0), e2 = std::exp(4.0), z = e0 + e1 + e2;
  EXPECT_NEAR(w[0][0].item<double>(), 3 * e0 / z, 1e-5);
  EXPECT_NEAR(w[1][0].item<double>(), 3 * e1 / z, 1e-5);
  EXPECT_NEAR(w[2][0].item<double>(), 3 * e2 / z, 1e-5);
}

TEST(Keyframe, WeightedLossByHand) {
  torch::Tensor pred = t2({{1.0f, 0.0f}, {0.0f, 0.0f}}), target = t2({{0.0f, 0.0f}, {0.0f, 2.0f}});
  // Per-sample weights: mean over components, weighted, mean over samples.
  torch::Tensor w1 = torch::tensor({5.0f, 1.0f});
  EXPECT_NEAR(action_loss("l1", pred, target, w1).item<double>(), (5 * 0.5 + 1 * 1.0) / 2, 1e-6);
  // Per-component weights.
  torch::Tensor w2 = t2({{5.0f, 1.0f}, {1.0f, 5.0f}});
  EXPECT_NEAR(action_loss("l1", pred, target, w2).item<double>(), (5 * 1 + 5 * 2) / 4.0, 1e-6);
}

// ---- fca ----------------------------------------------------------------------------------

TEST(Fca, AdversaryLossByHand) {
  torch::nn::Sequential d(torch::nn::Linear(3, 2));
  {
    torch::NoGradGuard ng;
    auto* lin = d[0]->as<torch::nn::Linear>();
    lin->weight.copy_(t2({{1, 0, 0}, {0, 1, 1}}));
    lin->bias.zero_();
  }
  torch::Tensor emb = t2({{1.0f}, {2.0f}}), a = t2({{0.5f, 0.5f}, {1.0f, 0.0f}});
  torch::Tensor prev = t2({{0.0f, 0.0f}, {2.0f, 2.0f}});
  // D([e, a]) = (e, a0 + a1): (1, 1) and (2, 1); errors (1, 1) and (0, -1).
  EXPECT_NEAR(fca_adversary_loss(d, emb, a, prev).item<double>(), (2.0 + 1.0) / 2, 1e-6);
}

TEST(Fca, AdversaryAndEncoderStepsMoveItsLossInOppositeDirections) {
  torch::manual_seed(4);
  Settings s = tiny_settings();
  s.fca.adversary_weight = 50.0;  // the encoder step is dominated by fooling D
  PolicyNets nets(policy_layout("fca", s.model, s.residual, s.fca, 2, 16, 16, 2));
  ASSERT_TRUE(nets.adversary);
  torch::optim::Adam opt(nets.parameters(), torch::optim::AdamOptions(1e-2).betas({0.5, 0.999}));
  PolicyBatch b = random_batch(16, 1);
  // The previous action is a function of the frames: something an encoder could expose.
  b.previous = b.image.mean({1, 2, 3}).view({16, 1, 1}).expand({16, 1, 2}).contiguous();
  auto d_loss = [&] {
    torch::NoGradGuard ng;
    nets.set_training(false);
    PolicyOutput out = nets.policy->forward(b.image, b.speed_in, b.command, false);
    double v = fca_adversary_loss(nets.adversary, out.embedding, b.action, b.previous.select(1, 0))
                   .item<double>();
    nets.set_training(true);
    return v;
  };
  nets.set_training(true);
  for (int i = 0; i < 3; ++i) fca_step(nets, opt, b, s, 0);
  // A D step alone lowers D's loss; an E + F step alone (D fixed) raises it.
  const std::vector<torch::Tensor> adv = nets.adversary_parameters();
  std::vector<torch::Tensor> enc;
  for (const auto& p : nets.policy->parameters()) enc.push_back(p);
  auto step_only = [&](bool adversary_step) {
    clear_grads(nets.parameters());
    PolicyOutput out = nets.policy->forward(b.image, b.speed_in, b.command, true);
    const torch::Tensor prev = b.previous.select(1, 0);
    if (adversary_step) {
      fca_adversary_loss(nets.adversary, out.embedding.detach(), b.action, prev).backward();
    } else {
      (policy_loss(s, out, b.action, b.speed_label) -
       s.fca.adversary_weight * fca_adversary_loss(nets.adversary, out.embedding, b.action, prev))
          .backward();
      clear_grads(adv);
    }
    opt.step();
  };
  const double before_d = d_loss();
  step_only(true);
  const double after_d = d_loss();
  EXPECT_LT(after_d, before_d);
  std::vector<torch::Tensor> adv_before;
  for (const auto& p : adv) adv_before.push_back(p.detach().clone());
  step_only(false);
  const double after_e = d_loss();
  EXPECT_GT(after_e, after_d);
  for (size_t i = 0; i < adv.size(); ++i) EXPECT_TRUE(torch::equal(adv[i], adv_before[i]));
}

// ---- hd -----------------------------------------------------------------------------------

TEST(Hd, DropsPastFramesAtItsRateAndNeverTheCurrent) {
  torch::manual_seed(5);
  torch::Tensor image = torch::ones({4000, 6, 2, 2});
  torch::Tensor keep = history_dropout(image, 2, 0.3);
  const double kept = keep.mean().item<double>();
  EXPECT_NEAR(kept, 0.7, 0.03);  // 4000 draws: sd 0.007
  for (int64_t i = 0; i < 4000; i += 97) {
    EXPECT_EQ(image[i].narrow(0, 4, 2).sum().item<float>(), 8.0f);  // the current frame
    EXPECT_EQ(image[i].narrow(0, 0, 4).sum().item<float>(), keep[i].item<float>() * 16.0f);
  }
}

// ---- the family trainer -----------------------------------------------------------------

std::string train(const TempDir& dir, const std::string& method, const std::string& name,
                  int epochs, const Settings& base) {
  Settings s = base;
  s.train.epochs = epochs;
  s.train.val_fraction = 0.34;
  s.keyframe.epochs = 2;
  s.keyframe.actions = 3;
  TrainRequest req;
  req.method = method;
  req.data_dir = dir / "data";
  req.out_dir = dir / name;
  req.quiet = true;
  TrainSummary sum = train_method(s, req);
  EXPECT_EQ(sum.epochs_done, epochs);
  return req.out_dir;
}

class FamilyMethods : public ::testing::TestWithParam<std::string> {};

TEST_P(FamilyMethods, SameSeedSameBytesAndResumeEqualsOneRun) {
  const std::string method = GetParam();
  TempDir dir("cd-s001-" + method);
  test::write_fake_folder(dir / "data", 3, {.frames = 24, .channels = 2, .height = 16, .width = 16});
  Settings s = tiny_settings();
  const std::string a = train(dir, method, "a", 2, s);
  const std::string b = train(dir, method, "b", 2, s);
  train(dir, method, "c", 1, s);
  const std::string c = train(dir, method, "c", 2, s);  // resumed after epoch 1
  for (const char* f : {kModelFile, kBestFile}) {
    EXPECT_EQ(test::read_text(a + "/" + f), test::read_text(b + "/" + f)) << f;
    EXPECT_EQ(test::read_text(a + "/" + f), test::read_text(c + "/" + f)) << f;
  }
  Checkpoint ck = require_checkpoint(a);
  EXPECT_EQ(ck.method, method);
  if (method == "keyframe") {
    ASSERT_TRUE(ck.method_record.contains("thresholds"));
    EXPECT_EQ(ck.method_record["thresholds"].size(), 2u);
  }

  // It drives as an agent: frames in, a valid control out.
  std::unique_ptr<Agent> agent = make_agent(method, a, s);
  EXPECT_EQ(agent->history(), 3);
  EpisodeSet set = load_episode_set(dir / "data");
  std::vector<std::vector<uint8_t>> buffers(3, std::vector<uint8_t>(set.frame_values()));
  Observation obs;
  obs.channels = 2;
  obs.height = obs.width = 16;
  for (int k = 0; k < 3; ++k) {
    set.planes255(0, 10 + k, buffers[k].data());
    obs.frames.push_back(buffers[k].data());
  }
  agent->begin_episode();
  Control ctl = agent->act(obs);
  EXPECT_GE(ctl.throttle, 0.0);
  EXPECT_LE(ctl.throttle, 1.0);
  EXPECT_GE(ctl.brake, 0.0);
  EXPECT_LE(ctl.brake, 1.0);

  // A folder of another method is refused, and so is one trained with other method settings.
  EXPECT_THROW(make_agent(method == "hd" ? "fca" : "hd", a, s), ConfigError);
  Settings other = s;
  other.residual.branches = 2;
  other.fca.adversary_weight = 1.0;
  other.keyframe.top_weight = 3.0;
  other.hd.p = 0.25;
  EXPECT_THROW(train(dir, method, "a", 3, other), ConfigError);
}

INSTANTIATE_TEST_SUITE_P(Seed001, FamilyMethods,
                         ::testing::Values("residual", "fca", "keyframe", "hd"));

TEST(ResidualController, AddsThePredictedResidualToTheExecutedAction) {
  TempDir dir("cd-s001-rc");
  test::write_fake_folder(dir / "data", 3, {.frames = 24, .channels = 2, .height = 16, .width = 16});
  Settings s = tiny_settings();
  s.residual.policy = "residual_controller";
  const std::string run = train(dir, "residual", "rc", 1, s);
  PolicyRunner runner(run, "residual");
  EpisodeSet set = load_episode_set(dir / "data");
  std::vector<std::vector<uint8_t>> buffers(3, std::vector<uint8_t>(set.frame_values()));
  std::vector<const uint8_t*> frames;
  for (int k = 0; k < 3; ++k) {
    set.planes255(1, 5 + k, buffers[k].data());
    frames.push_back(buffers[k].data());
  }
  const float zero[2] = {0, 0}, prev[2] = {0.25f, 0.5f};
  runner.run(frames.data(), 0, 0, zero);
  const std::vector<float> residual = runner.last_action();
  runner.run(frames.data(), 0, 0, prev);
  EXPECT_NEAR(runner.last_action()[0], 0.25f + residual[0], 1e-5);
  EXPECT_NEAR(runner.last_action()[1], 0.5f + residual[1], 1e-5);
}

TEST(FamilyErrors, OneClearLinePerBadSetting) {
  TempDir dir("cd-s001-err");
  test::write_fake_folder(dir / "data", 2, {.frames = 12, .channels = 2, .height = 16, .width = 16});
  Settings s = tiny_settings();
  s.model.history = 1;
  EXPECT_THROW(train(dir, "hd", "hd1", 1, s), ConfigError);
  EXPECT_THROW(train(dir, "residual", "r1", 1, s), ConfigError);
  s = tiny_settings();
  s.model.action_head = "target_speed";
  EXPECT_THROW(train(dir, "residual", "r2", 1, s), ConfigError);
  EXPECT_THROW(train(dir, "fca", "f2", 1, s), ConfigError);
}

}  // namespace
}  // namespace cd
