// model.pedals = "signed": the action as throttle - brake[, steer] (the seeds' throttle_brake),
// by hand; the dataset's labels and previous actions in that space; a trained policy whose
// runner decodes it (never both pedals), residual's memory-only controller adding its residual
// in that space; and MuJoCo data refused.
#include <cmath>

#include <gtest/gtest.h>

#include <torch/torch.h>

#include <vector>

#include "../support/fake_episodes.hpp"
#include "../support/tiny_training.hpp"
#include "core/error.hpp"
#include "datasets/dataset.hpp"
#include "inference/policy_runner.hpp"
#include "nn/model_settings.hpp"
#include "runs/checkpoint.hpp"

namespace cd {
namespace {

using test::TempDir;

TEST(Pedals, SignedValueByHand) {
  float learned[2], recorded[3];
  const float accelerate[3] = {0.3f, 0.0f, 0.2f};
  pedals_to_learned(accelerate, 3, learned);
  EXPECT_FLOAT_EQ(learned[0], 0.3f);
  EXPECT_FLOAT_EQ(learned[1], 0.2f);
  const float brake[2] = {0.0f, 0.5f};
  pedals_to_learned(brake, 2, learned);
  EXPECT_FLOAT_EQ(learned[0], -0.5f);
  const float back[2] = {-0.5f, -0.1f};
  pedals_to_recorded(back, 3, recorded);
  EXPECT_EQ(std::vector<float>(recorded, recorded + 3), (std::vector<float>{0.0f, 0.5f, -0.1f}));
  const float go[1] = {0.7f};
  pedals_to_recorded(go, 2, recorded);
  EXPECT_EQ(std::vector<float>(recorded, recorded + 2), (std::vector<float>{0.7f, 0.0f}));
}

TEST(Pedals, DatasetLabelsAndPreviousActionsAreThrottleMinusBrake) {
  TempDir dir("cd-pedals-data");
  test::write_fake_folder(dir / "data", 3, {.frames = 30});
  DatasetOptions o;
  o.history = 2;
  o.stride = 1;
  o.action_lags = 2;
  o.signed_pedals = true;
  Dataset data(load_episode_set(dir / "data"), o);
  ASSERT_EQ(data.action_dim(), 1);
  // The fake action of step t of episode e is (t / 1000, e / 100).
  const SampleRef s = data.train()[5];
  std::vector<float> image(data.image_values()), previous(2);
  float speed = 0, action = 0, label = 0;
  int64_t command = 0;
  data.fill(s, {image.data(), &speed, &command, &action, &label, previous.data()});
  EXPECT_FLOAT_EQ(action, s.t / 1000.0f - s.episode / 100.0f);
  EXPECT_FLOAT_EQ(previous[0], (s.t - 1) / 1000.0f - s.episode / 100.0f);
  EXPECT_FLOAT_EQ(previous[1], (s.t - 2) / 1000.0f - s.episode / 100.0f);
}

std::string train_signed(const TempDir& dir, const std::string& method) {
  Settings s = test::tiny_family_settings();
  s.model.pedals = "signed";
  if (method == "residual") s.residual.policy = "residual_controller";
  return test::train_tiny_run(dir, method, method, s);
}

TEST(Pedals, ATrainedPolicyIsDecodedAndNeverPressesBoth) {
  torch::set_num_threads(1);
  TempDir dir("cd-pedals-train");
  test::write_fake_folder(dir / "data", 3, {.frames = 30});
  const std::string ck = train_signed(dir, "bc-oh");
  const Checkpoint record = require_checkpoint(ck);
  EXPECT_EQ(record.input.action_output, "tanh");
  EXPECT_EQ(record.input.action_dim, 2);  // as recorded
  PolicyRunner runner(ck);
  EpisodeSet set = load_episode_set(dir / "data");
  std::vector<std::vector<uint8_t>> frames(3, std::vector<uint8_t>(set.frame_values()));
  std::vector<const uint8_t*> ptr;
  for (auto& f : frames) ptr.push_back(f.data());
  for (int t = 4; t < 30; t += 3) {
    for (int k = 0; k < 3; ++k) set.planes255(0, t - (2 - k) * 2, frames[k].data());
    PolicyStep step = runner.run(ptr.data(), 0.0, 0);
    ASSERT_EQ(runner.last_action().size(), 2u);
    EXPECT_TRUE(step.throttle == 0.0 || step.brake == 0.0) << step.throttle << " " << step.brake;
    EXPECT_FLOAT_EQ(static_cast<float>(step.throttle), runner.last_action()[0]);
    EXPECT_FLOAT_EQ(static_cast<float>(step.brake), runner.last_action()[1]);
    EXPECT_GE(step.scalar(), -1.0);
    EXPECT_LE(step.scalar(), 1.0);
  }

  // residual's memory-only controller: a_t = a_{t-1} + its residual, in the signed space. Its
  // residual for these frames, r, is read behind a previous action of 0; then two previous
  // actions chosen so that both outputs lie inside (-1, 1), where nothing clamps them: r + 0.3
  // and r + 0.5 from a_{t-1} = 0.3 (throttle) and 0.5, and r - 0.4 from a brake of 0.4 (-0.4).
  const std::string rc = train_signed(dir, "residual");
  PolicyRunner controller(rc);
  for (int k = 0; k < 3; ++k) set.planes255(0, 10 - (2 - k) * 2, frames[k].data());
  const float still[2] = {0.0f, 0.0f};
  const double r = controller.run(ptr.data(), 0.0, 0, still).scalar();
  ASSERT_LT(std::abs(r), 0.45) << "a residual this large leaves no unclamped range to test";
  const float gentle[2] = {0.3f, 0.0f}, harder[2] = {0.5f, 0.0f}, braking[2] = {0.0f, 0.4f};
  const double a = controller.run(ptr.data(), 0.0, 0, gentle).scalar();
  const double b = controller.run(ptr.data(), 0.0, 0, harder).scalar();
  const double c = controller.run(ptr.data(), 0.0, 0, braking).scalar();
  EXPECT_NEAR(a, r + 0.3, 1e-5);
  EXPECT_NEAR(b - a, 0.2, 1e-5);
  EXPECT_NEAR(a - c, 0.7, 1e-5) << "a brake of 0.4 is -0.4: 0.7 below a throttle of 0.3";
}

TEST(Pedals, MujocoDataIsRefused) {
  TempDir dir("cd-pedals-mujoco");
  test::write_fake_folder(dir / "data", 2, {.frames = 10});
  EpisodeSet set = load_episode_set(dir / "data");
  set.domain = "mujoco";
  DatasetOptions o;
  o.signed_pedals = true;
  try {
    Dataset data(std::move(set), o);
    FAIL() << "no error";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("model.pedals"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace cd
