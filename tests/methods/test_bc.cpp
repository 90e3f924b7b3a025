// The bc agent (methods/bc) on a checkpoint trained in-process on hand-made episodes: it loads,
// drives through the runner's weights, checks its inputs; the target-speed head goes through the
// PID.
#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <vector>

#include <torch/torch.h>

#include "../support/fake_episodes.hpp"
#include "agents/agent.hpp"
#include "core/error.hpp"
#include "datasets/episode_set.hpp"
#include "inference/policy_runner.hpp"
#include "methods/method.hpp"
#include "train/request.hpp"

namespace cd {
namespace {

using test::TempDir;

struct TorchThreads {
  TorchThreads() { torch::set_num_threads(1); }
} const kOneThread;

// Trains a tiny checkpoint in-process.
std::string train_tiny(const TempDir& dir, const std::string& method, const std::string& head) {
  test::write_fake_folder(dir / "data", 3, {.frames = 30});
  Settings s;
  s.model.features = 16;
  s.model.history = 3;
  s.model.history_stride = 2;
  s.model.action_head = head;
  s.train.epochs = 1;
  s.train.batch_size = 16;
  s.train.threads = 1;
  s.train.val_fraction = 0.34;
  TrainRequest req;
  req.method = method;
  req.data_dir = dir / "data";
  req.out_dir = dir / ("ck-" + method + "-" + head);
  req.quiet = true;
  TrainSummary sum = train_method(s, req);
  EXPECT_EQ(sum.epochs_done, 1);
  EXPECT_EQ(sum.best_epoch, 1);
  EXPECT_EQ(sum.val_episodes, 1);
  return req.out_dir;
}

Observation observation(const EpisodeSet& set, int e, int t, int history, int stride,
                        std::vector<std::vector<uint8_t>>& buffers) {
  Observation obs;
  obs.channels = set.channels;
  obs.height = set.height;
  obs.width = set.width;
  buffers.assign(history, std::vector<uint8_t>(set.frame_values()));
  for (int k = 0; k < history; ++k) {
    set.planes255(e, t - (history - 1 - k) * stride, buffers[k].data());
    obs.frames.push_back(buffers[k].data());
  }
  obs.speed = set.episodes[e].speed[t];
  obs.command = set.episodes[e].command[t];
  return obs;
}

TEST(PolicyAgent, LoadsACheckpointAndDrives) {
  TempDir dir("cd-learn");
  const std::string ck = train_tiny(dir, "bc-oh", "throttle_brake");
  Settings s;
  s.ego.lateral = "route";  // the hand-made episodes hold (throttle, brake): no steer
  s.eval.device = "cpu";    // compared below with the runner's CPU forward pass
  std::unique_ptr<Agent> agent = make_agent("bc-oh", ck, s);
  EXPECT_EQ(agent->name(), "bc-oh");
  EXPECT_EQ(agent->history(), 3);
  EXPECT_EQ(agent->history_stride(), 2);
  EXPECT_EQ(torch::get_num_threads(), 1);
  EpisodeSet set = load_episode_set(dir / "data");
  std::vector<std::vector<uint8_t>> buffers;
  agent->begin_episode();
  bool differs = false;
  Control first{};
  for (int t = 4; t < 30; ++t) {
    Control c = agent->act(observation(set, 0, t, 3, 2, buffers));
    EXPECT_GE(c.throttle, 0.0);
    EXPECT_LE(c.throttle, 1.0);
    EXPECT_GE(c.brake, 0.0);
    EXPECT_LE(c.brake, 1.0);
    EXPECT_TRUE(std::isnan(agent->last_target_speed()));
    if (t == 4) first = c;
    else differs |= c.throttle != first.throttle || c.brake != first.brake;
  }
  EXPECT_TRUE(differs) << "the output should depend on the observation";

  // Same weights as best.pt through the runner: the agent adds nothing of its own.
  PolicyRunner runner(ck);
  Observation obs = observation(set, 1, 20, 3, 2, buffers);
  PolicyStep step = runner.run(obs.frames.data(), obs.speed, obs.command);
  Control c = agent->act(obs);
  EXPECT_FLOAT_EQ(static_cast<float>(c.throttle), static_cast<float>(step.throttle));

  // The method must match, and observations must have the checkpoint's shape.
  EXPECT_THROW(make_agent("bc-so", ck, s), ConfigError);
  obs.height = 64;
  EXPECT_THROW(agent->act(obs), ConfigError);
  EXPECT_THROW(make_agent("bc-oh", dir / "nothing-here", s), DataError);
}

TEST(PolicyAgent, TargetSpeedHeadGoesThroughThePid) {
  TempDir dir("cd-learn");
  const std::string ck = train_tiny(dir, "bc-so", "target_speed");
  Settings s;
  s.ego.lateral = "route";  // a target-speed head learns no steer
  std::unique_ptr<Agent> agent = make_agent("bc-so", ck, s);
  EXPECT_EQ(agent->history(), 1);
  EpisodeSet set = load_episode_set(dir / "data");
  std::vector<std::vector<uint8_t>> buffers;
  agent->begin_episode();
  for (int t = 0; t < 10; ++t) {
    Control c = agent->act(observation(set, 0, t, 1, 1, buffers));
    double target = agent->last_target_speed();
    ASSERT_TRUE(std::isfinite(target));
    EXPECT_GE(target, 0.0);
    EXPECT_GE(c.throttle, 0.0);
    EXPECT_LE(c.throttle, 1.0);
    EXPECT_GE(c.brake, 0.0);
    EXPECT_LE(c.brake, 1.0);
  }
}

}  // namespace
}  // namespace cd
