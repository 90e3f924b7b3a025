// The episode runner (bench/runner) in the live world: classification of scripted episodes
// (inertia, timeout, success), SUMO's teleport of a standing ego, the leader scenario, cross
// traffic that never blocks the path.
//
// libsumo runs one simulation per process and ctest runs every TEST in its own process, so
// each TEST below creates at most one World.
// needs: sumo
#include "bench/runner.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

#include "../support/test_support.hpp"
#include "agents/agent.hpp"
#include "app/settings.hpp"
#include "methods/method.hpp"
#include "world/world.hpp"

namespace cd {
namespace {

using test::TempDir;

Settings test_settings(const std::string& traffic = "empty", const std::string& extra = "") {
  TempDir dir("cdtest-bench");
  return load_settings(test::write_test_config(dir, traffic, extra));
}


// Stands still whatever happens.
class BrakeAgent : public Agent {
 public:
  std::string name() const override { return "brake"; }
  bool uses_frames() const override { return false; }
  Control act(const Observation&) override { return {0.0, 1.0}; }
};

TEST(BenchEpisode, StoppedWithAFreePathIsStuck) {
  Settings s = test_settings();
  World world(s);
  Task task = world.sample_scenario_task(11, "route", 150, 300);
  task.timeout_s = 20;
  BrakeAgent agent;
  EpisodeResult r = run_episode(world, agent, task, s);
  EXPECT_EQ(r.outcome, "stuck");
  EXPECT_TRUE(r.paper_inertia);
  EXPECT_EQ(r.last_stop_cause, "free");
  ASSERT_EQ(r.final_max_speed.size(), 15u);
  for (double v : r.final_max_speed) EXPECT_LT(v, kStoppedSpeed);
  ASSERT_EQ(r.events.size(), 1u);  // the free path at the takeover, never taken
  EXPECT_EQ(r.events[0].kind, "start");
  EXPECT_FALSE(r.events[0].started);
  EXPECT_TRUE(r.events[0].stall);
  EXPECT_NEAR(r.duration_s, 20.0 - s.eval.prefill_s, 0.11);
}

TEST(BenchEpisode, StoppedBehindAStoppedCarIsBlocked) {
  Settings s = test_settings();
  World world(s);
  Task task = world.sample_scenario_task(12, "leader", 150, 300);
  task.leader_hold_s = 1e9;  // the leader never leaves
  task.timeout_s = 20;
  BrakeAgent agent;
  EpisodeResult r = run_episode(world, agent, task, s);
  EXPECT_EQ(r.outcome, "blocked");
  EXPECT_EQ(r.last_stop_cause, "leader");
  EXPECT_TRUE(r.events.empty());
}

TEST(BenchEpisode, StoppedAtRedIsBlockedWithoutEvents) {
  Settings s = test_settings();
  World world(s);
  Task task = world.sample_scenario_task(13, "red_light", 150, 300);
  task.timeout_s = 16;  // longer than the inertia span, shorter than a red phase
  world.reset(task);
  EXPECT_EQ(world.truth().tl_state, kTlRed);
  EXPECT_LT(world.truth().tl_distance, 3.0);  // first in line at the stop line
  EXPECT_FALSE(world.truth().path_free);
  BrakeAgent agent;
  EpisodeResult r = run_episode(world, agent, task, s);
  EXPECT_EQ(r.outcome, "blocked");
  EXPECT_EQ(r.last_stop_cause, "red_light");
  EXPECT_TRUE(r.paper_inertia) << "seed 000's rule: it stood the last 15 s";
  EXPECT_TRUE(r.events.empty());
}

// SUMO teleports a car that stood 90 s, and may put it back further along in the same step:
// for the ego that ends the episode where it stood (before this was handled, a frozen policy
// reappeared beyond the junction and "succeeded").
TEST(BenchEpisode, StandingUntilSumoTeleportsTheEgoEndsTheEpisodeWhereItStood) {
  Settings s = test_settings();
  World world(s);
  BrakeAgent agent;
  // A free road: stuck when SUMO gives up on the ego.
  Task road = world.sample_scenario_task(11, "route", 150, 300);
  road.timeout_s = 300;
  EpisodeResult r = run_episode(world, agent, road, s);
  EXPECT_EQ(r.outcome, "stuck");
  EXPECT_LT(r.duration_s, 95.0);
  EXPECT_LT(r.distance_m, 0.5);
  // First at a light that turns green and back to red while the ego stands: a stalled
  // stop-and-go event that never started, a restart stall (the light blocks the last seconds,
  // so it is not stuck).
  Task light = world.sample_scenario_task(13, "red_light", 150, 300);
  light.timeout_s = 300;
  r = run_episode(world, agent, light, s);
  EXPECT_EQ(r.outcome, "restart_stall");
  EXPECT_LT(r.duration_s, 95.0);
  EXPECT_LT(r.distance_m, 0.5);
  ASSERT_EQ(r.events.size(), 1u);
  EXPECT_EQ(r.events[0].kind, "freed");
  EXPECT_TRUE(r.events[0].stall);
  EXPECT_FALSE(r.events[0].started);
}

TEST(BenchEpisode, LeaderDrivesOffAndTheExpertFollows) {
  Settings s = test_settings();
  World world(s);
  Task task = world.sample_scenario_task(14, "leader", 150, 300);
  world.reset(task);
  EXPECT_TRUE(world.truth().lead_present);
  EXPECT_NEAR(world.truth().lead_distance, task.leader_gap, 0.5);
  EXPECT_FALSE(world.truth().path_free);
  auto expert = make_agent("expert", "", s, &world);
  EpisodeResult r = run_episode(world, *expert, task, s);
  EXPECT_EQ(r.outcome, "success");
}

// Brakes and keeps every frame it is shown; with `world`, also what the world itself renders
// at that moment (act() is called right after the runner made the observation).
class FrameAgent : public Agent {
 public:
  explicit FrameAgent(const World* world = nullptr) : world_(world) {}
  std::string name() const override { return "frames"; }
  Control act(const Observation& obs) override {
    const size_t n = size_t(obs.channels) * obs.height * obs.width;
    seen.emplace_back(obs.frames.back(), obs.frames.back() + n);
    if (world_) {
      truth.emplace_back(n);
      world_->render(truth.back().data());
    }
    return {0.0, 1.0};
  }
  std::vector<std::vector<uint8_t>> seen, truth;

 private:
  const World* world_;
};

// eval.sensor in the episode runner: the clean sensor is the world's own BEV; the shifted one
// gives the agent other frames, the same ones on a rerun, others for another sensor seed, and
// leaves the world (what the expert and the ground truth use) untouched.
TEST(BenchEpisode, SensorShiftReachesTheAgentOnlyAndIsDeterministic) {
  Settings s = test_settings("regular");
  World world(s);
  Task task = world.sample_scenario_task(15, "route", 150, 300);
  task.timeout_s = 3;
  FrameAgent clean(&world);
  EpisodeResult rc = run_episode(world, clean, task, s);
  ASSERT_GT(clean.seen.size(), 10u);
  EXPECT_EQ(clean.seen, clean.truth) << "the clean sensor is the world's BEV";

  s.eval.sensor = "shifted";
  FrameAgent a(&world), b, other;
  EpisodeResult ra = run_episode(world, a, task, s);
  run_episode(world, b, task, s);
  ASSERT_EQ(a.seen.size(), clean.seen.size());
  EXPECT_EQ(a.truth, clean.truth) << "the world is the same whatever the agent's sensor";
  EXPECT_EQ(episode_to_json(ra).dump(), episode_to_json(rc).dump()) << "a braking agent's episode";
  EXPECT_EQ(a.seen, b.seen) << "same sensor seed, task, trial and steps: same bytes";
  int differ = 0;
  for (size_t i = 0; i < a.seen.size(); ++i) differ += a.seen[i] != clean.seen[i];
  EXPECT_GT(differ, static_cast<int>(a.seen.size()) / 2) << "most shifted frames differ";
  s.eval.sensor_shift.seed = 99;
  run_episode(world, other, task, s);
  EXPECT_NE(other.seen, a.seen) << "another sensor seed, other noise";
}

// Cross traffic through the junction in front of an ego waiting first in line at a red
// light is never "on the path": the path is blocked by the light only.
TEST(BenchEpisode, CrossTrafficInFrontDoesNotBlockThePath) {
  Settings s = test_settings("dense", "");
  s.world.warmup_s = 60;
  World world(s);
  int crossings = 0;
  for (uint64_t seed = 20; seed < 30 && crossings < 20; ++seed) {
    Task task = world.sample_scenario_task(seed, "red_light", 150, 300);
    world.reset(task);
    const Vec2 front = world.ego().pose.pos;
    while (world.truth().tl_state == kTlRed && world.time() < 60) {
      const Pose2 ego = world.ego().pose;
      for (const Actor& a : world.actors()) {
        if (a.pedestrian) continue;
        Vec2 d = a.box.center - ego.pos;
        double ahead = d.x * std::cos(ego.heading) + d.y * std::sin(ego.heading);
        double turn = std::abs(std::remainder(a.box.heading - ego.heading, 2 * M_PI));
        if (ahead > 3 && ahead < 20 && turn > M_PI / 4 && turn < 3 * M_PI / 4 && a.speed > 1) {
          ++crossings;
          EXPECT_FALSE(world.truth().lead_present && world.truth().lead_distance < 6.0)
              << "crossing car " << a.id << " counted as a leader";
        }
      }
      ASSERT_EQ(world.step(Control{0, 1}).outcome, Outcome::Running);
      EXPECT_LT((world.ego().pose.pos - front).norm(), 0.5);
    }
  }
  EXPECT_GT(crossings, 0) << "no cross traffic seen: the test checked nothing";
}

}  // namespace
}  // namespace cd
