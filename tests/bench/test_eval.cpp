// The closed-loop benchmark: classification on scripted episodes in the real world, the
// built-in suites, and `causaldrive eval` end to end (results, determinism, resume, crashes).
//
// libsumo runs one simulation per process and ctest runs every TEST in its own process, so
// each TEST below creates at most one World.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <thread>

#include <nlohmann/json.hpp>

#include "agents/agent.hpp"
#include "bench/runner.hpp"
#include "methods/method.hpp"
#include "bench/suite.hpp"
#include "core/error.hpp"
#include "../support/test_support.hpp"
#include "world/world.hpp"

namespace cd {
namespace {

using test::TempDir;
namespace fs = std::filesystem;

Settings test_settings(const std::string& traffic = "empty", const std::string& extra = "") {
  TempDir dir("cdtest-bench");
  return load_settings(test::write_test_config(dir, traffic, extra));
}

// Stands still whatever happens.
class BrakeAgent : public Agent {
 public:
  std::string name() const override { return "brake"; }
  bool uses_frames() const override { return false; }
  Control act(const Observation&, const World&) override { return {0.0, 1.0}; }
};

nlohmann::json read_json(const std::string& path) {
  return nlohmann::json::parse(test::read_text(path));
}

TEST(BenchEpisode, StoppedWithAFreePathIsInertia) {
  Settings s = test_settings();
  World world(s);
  Task task = world.sample_scenario_task(11, "route", 150, 300);
  task.timeout_s = 20;
  BrakeAgent agent;
  EpisodeResult r = run_episode(world, agent, task, s);
  EXPECT_EQ(r.outcome, "inertia");
  ASSERT_EQ(r.events.size(), 1u);  // the free path at the takeover, never taken
  EXPECT_EQ(r.events[0].kind, "start");
  EXPECT_FALSE(r.events[0].started);
  EXPECT_TRUE(r.events[0].stall);
  EXPECT_NEAR(r.duration_s, 20.0 - s.eval.prefill_s, 0.11);
}

TEST(BenchEpisode, StoppedBehindAStoppedCarIsATimeout) {
  Settings s = test_settings();
  World world(s);
  Task task = world.sample_scenario_task(12, "leader", 150, 300);
  task.leader_hold_s = 1e9;  // the leader never leaves
  task.timeout_s = 20;
  BrakeAgent agent;
  EpisodeResult r = run_episode(world, agent, task, s);
  EXPECT_EQ(r.outcome, "timeout");
  EXPECT_TRUE(r.events.empty());
}

TEST(BenchEpisode, StoppedAtRedIsATimeoutWithoutEvents) {
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
  EXPECT_EQ(r.outcome, "timeout");
  EXPECT_TRUE(r.events.empty());
}

// SUMO teleports a car that stood 90 s, and may put it back further along in the same step:
// for the ego that ends the episode where it stood (before this was handled, a frozen policy
// reappeared beyond the junction and "succeeded").
TEST(BenchEpisode, StandingUntilSumoTeleportsTheEgoEndsTheEpisodeWhereItStood) {
  Settings s = test_settings();
  World world(s);
  BrakeAgent agent;
  // A free road: inertia when SUMO gives up on the ego.
  Task road = world.sample_scenario_task(11, "route", 150, 300);
  road.timeout_s = 300;
  EpisodeResult r = run_episode(world, agent, road, s);
  EXPECT_EQ(r.outcome, "inertia");
  EXPECT_LT(r.duration_s, 95.0);
  EXPECT_LT(r.distance_m, 0.5);
  // First at a light that turns green and back to red while the ego stands: a stalled
  // stop-and-go event that never started, and a timeout (the light blocks the last seconds).
  Task light = world.sample_scenario_task(13, "red_light", 150, 300);
  light.timeout_s = 300;
  r = run_episode(world, agent, light, s);
  EXPECT_EQ(r.outcome, "timeout");
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
  auto expert = make_agent("expert", "", s);
  EpisodeResult r = run_episode(world, *expert, task, s);
  EXPECT_EQ(r.outcome, "success");
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

TEST(BenchSuites, BuiltInSuitesMatchTheContract) {
  for (const std::string& name : builtin_suite_names()) {
    SCOPED_TRACE(name);
    Suite s = load_suite(name);
    EXPECT_EQ(s.name, name);
    ASSERT_FALSE(s.tasks.empty());
    const bool stopgo = name.size() > 7 && name.substr(name.size() - 7) == "-stopgo";
    if (name != "quickstart") {
      EXPECT_EQ(s.tasks.size(), 25u);
      EXPECT_EQ(s.trials, 3);
    }
    int red = 0, leader = 0;
    for (const Task& t : s.tasks) {
      if (!stopgo && name != "quickstart") {
        EXPECT_EQ(t.scenario, "route");
        EXPECT_GE(t.route_length, 300.0);
      }
      double expected = t.route_length / (5.0 / 3.6) + 20.0 + (t.scenario == "red_light" ? 60 : 0);
      EXPECT_NEAR(t.timeout_s, expected, 1e-6);
      red += t.scenario == "red_light";
      leader += t.scenario == "leader";
    }
    if (stopgo) {
      EXPECT_GE(red, 10);
      EXPECT_GE(leader, 10);
    }
  }
  EXPECT_THROW(load_suite("town-z-regular"), ConfigError);
}

TEST(BenchSuites, RegeneratingGivesTheFilesInTheRepo) {
  TempDir dir("cdtest-suites");
  auto r = test::run_cli({"suite", "--builtin", "all", "--out", dir.path()});
  ASSERT_TRUE(r.exited && r.exit_code == 0) << r.describe();
  for (const std::string& name : builtin_suite_names()) {
    SCOPED_TRACE(name);
    EXPECT_EQ(test::read_text(dir / (name + ".json")),
              test::read_text(std::string(CD_SOURCE_DIR) + "/suites/" + name + ".json"));
  }
}

TEST(BenchSuites, DamagedSuiteFileIsOneClearError) {
  TempDir dir("cdtest-suites");
  test::write_text(dir / "bad.json", "{\"format\": 1, \"name\": \"x\"");
  auto r = test::run_cli({"eval", "--agent", "expert", "--suite", dir / "bad.json", "--out",
                          dir / "out"});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_EQ(test::split_lines(r.err).size(), 1u) << r.err;
  EXPECT_NE(r.err.find("bad.json"), std::string::npos);
  test::write_text(dir / "nokey.json", "{\"format\": 1, \"name\": \"x\", \"town\": \"town-a\"}");
  r = test::run_cli({"eval", "--agent", "expert", "--suite", dir / "nokey.json", "--out",
                     dir / "out2"});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("traffic"), std::string::npos) << r.err;
}

// A suite of short tasks with traffic, made with the CLI like a user would.
std::string make_small_suite(const TempDir& dir, int tasks) {
  const std::string path = dir / "small.json";
  auto r = test::run_cli({"suite", "--town", "town-a", "--traffic", "regular", "--tasks",
                          std::to_string(tasks), "--trials", "1", "--seed", "5", "--min-route",
                          "150", "--max-route", "250", "--scenarios", "route", "red_light",
                          "leader", "--out", path});
  if (!r.exited || r.exit_code != 0) throw std::runtime_error(r.describe());
  return path;
}

test::CommandResult eval_cli(const std::string& config, const std::string& suite,
                             const std::string& out, const std::string& agent = "expert",
                             const std::string& workers = "2") {
  return test::run_cli({"eval", "--config", config, "--agent", agent, "--suite", suite,
                        "--workers", workers, "--out", out, "--quiet"});
}

TEST(BenchEval, ResultsHaveTheContractKeysAndTheExpertSucceeds) {
  TempDir dir("cdtest-eval");
  const std::string cfg = test::write_test_config(dir);
  auto r = eval_cli(cfg, "quickstart", dir / "out");
  ASSERT_TRUE(r.exited && r.exit_code == 0) << r.describe();
  EXPECT_NE(r.out.find("| expert | quickstart |"), std::string::npos) << r.out;
  nlohmann::json res = read_json(dir / "out/results.json");
  EXPECT_EQ(res["agent"], "expert");
  EXPECT_EQ(res["suite"], "quickstart");
  ASSERT_EQ(res["episodes"].size(), 4u);
  const nlohmann::json& s = res["summary"];
  for (const char* k : {"success_rate", "collision_rate", "inertia_rate", "timeout_rate",
                        "error_rate", "stall_rate", "route_completion"}) {
    ASSERT_TRUE(s.contains(k)) << k;
    EXPECT_GE(s[k].get<double>(), 0.0) << k;
    EXPECT_LE(s[k].get<double>(), 1.0) << k;
  }
  for (const char* k : {"stop_go_events", "start_delay_median_s", "start_delay_p90_s",
                        "red_light_violations_per_km", "mean_speed"})
    EXPECT_TRUE(s.contains(k)) << k;
  EXPECT_DOUBLE_EQ(s["success_rate"].get<double>(), 1.0);
  EXPECT_DOUBLE_EQ(s["error_rate"].get<double>(),
                   s["collision_rate"].get<double>() + s["inertia_rate"].get<double>());
  // The red-light and leader tasks make stop-and-go events; the expert never stalls.
  EXPECT_GE(s["stop_go_events"].get<int>(), 2);
  EXPECT_EQ(s["stalls"].get<int>(), 0);
  for (const auto& e : res["episodes"]) EXPECT_EQ(e["outcome"], "success");
}

TEST(BenchEval, SameSeedSameBytesWhateverTheWorkerCount) {
  TempDir dir("cdtest-eval");
  const std::string cfg = test::write_test_config(dir);
  const std::string suite = make_small_suite(dir, 4);
  auto a = eval_cli(cfg, suite, dir / "a", "cs", "1");
  auto b = eval_cli(cfg, suite, dir / "b", "cs", "2");
  ASSERT_EQ(a.exit_code, 0) << a.describe();
  ASSERT_EQ(b.exit_code, 0) << b.describe();
  EXPECT_EQ(test::read_text(dir / "a/results.json"), test::read_text(dir / "b/results.json"));
}

TEST(BenchEval, KilledRunResumesWithNothingLostOrCountedTwice) {
  TempDir dir("cdtest-eval");
  const std::string cfg = test::write_test_config(dir, "regular");
  const std::string suite = make_small_suite(dir, 9);
  auto ref = eval_cli(cfg, suite, dir / "ref", "expert", "1");
  ASSERT_EQ(ref.exit_code, 0) << ref.describe();

  std::vector<std::string> argv = {CD_BINARY, "eval", "--config", cfg, "--agent", "expert",
                                   "--suite", suite, "--workers", "1", "--out", dir / "run",
                                   "--quiet"};
  pid_t pid = test::spawn_group(argv, dir / "stdout", dir / "stderr");
  // Kill the whole process group as soon as a few episodes are recorded.
  auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(120);
  while (std::chrono::steady_clock::now() < deadline) {
    auto names = test::list_dir(dir / "run/episodes");
    if (std::count_if(names.begin(), names.end(),
                      [](const std::string& n) { return test::ends_with(n, ".json"); }) >= 3)
      break;
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  ::kill(-pid, SIGKILL);
  int status = 0;
  ::waitpid(pid, &status, 0);
  ASSERT_TRUE(WIFSIGNALED(status)) << "the run finished before it could be killed";
  EXPECT_FALSE(fs::exists(dir / "run/results.json"));

  auto again = eval_cli(cfg, suite, dir / "run", "expert", "1");
  ASSERT_EQ(again.exit_code, 0) << again.describe();
  EXPECT_NE(again.out.find("episodes run now"), std::string::npos);
  EXPECT_EQ(test::read_text(dir / "run/results.json"), test::read_text(dir / "ref/results.json"));
  nlohmann::json res = read_json(dir / "run/results.json");
  ASSERT_EQ(res["episodes"].size(), 9u);
  for (int i = 0; i < 9; ++i) EXPECT_EQ(res["episodes"][i]["index"], i);
}

TEST(BenchEval, CrashedEpisodeIsRetriedAndNeverCountedAsAPolicyFailure) {
  TempDir dir("cdtest-eval");
  const std::string cfg = test::write_test_config(dir);
  auto ref = eval_cli(cfg, "quickstart", dir / "ref");
  ASSERT_EQ(ref.exit_code, 0) << ref.describe();

  ::setenv("CAUSALDRIVE_INJECT_CRASH", "eval:1", 1);  // the first run of episode 1 is killed
  auto once = eval_cli(cfg, "quickstart", dir / "once");
  ::setenv("CAUSALDRIVE_INJECT_CRASH", "eval:2:always", 1);  // episode 2 always dies
  auto always = eval_cli(cfg, "quickstart", dir / "always");
  ::unsetenv("CAUSALDRIVE_INJECT_CRASH");

  ASSERT_EQ(once.exit_code, 0) << once.describe();
  EXPECT_TRUE(fs::exists(dir / "once/.crash-injected-eval-1"));
  EXPECT_EQ(test::read_text(dir / "once/results.json"), test::read_text(dir / "ref/results.json"));

  ASSERT_EQ(always.exit_code, 0) << always.describe();
  EXPECT_NE(always.err.find("not counted"), std::string::npos) << always.err;
  nlohmann::json res = read_json(dir / "always/results.json");
  EXPECT_EQ(res["summary"]["infrastructure_failures"], 1);
  EXPECT_EQ(res["summary"]["episodes"], 3);
  EXPECT_DOUBLE_EQ(res["summary"]["success_rate"].get<double>(), 1.0);
  EXPECT_EQ(res["episodes"][2]["outcome"], "infrastructure_failure");
  // The next run retries it, and then the results are complete.
  auto retry = eval_cli(cfg, "quickstart", dir / "always");
  ASSERT_EQ(retry.exit_code, 0) << retry.describe();
  EXPECT_EQ(test::read_text(dir / "always/results.json"), test::read_text(dir / "ref/results.json"));
}

TEST(BenchEval, BadRequestsGiveOneLineAndExitOne) {
  TempDir dir("cdtest-eval");
  const std::string cfg = test::write_test_config(dir);
  auto check = [&](const std::vector<std::string>& args, const std::string& needle) {
    auto r = test::run_cli(args);
    EXPECT_TRUE(r.exited && r.exit_code == 1) << r.describe();
    EXPECT_EQ(test::split_lines(r.err).size(), 1u) << r.err;
    EXPECT_NE(r.err.find(needle), std::string::npos) << r.err;
  };
  check({"eval", "--config", cfg, "--agent", "nobody", "--out", dir / "o1"}, "unknown agent");
  check({"eval", "--config", cfg, "--agent", "expert", "--suite", "town-q-dense", "--out",
         dir / "o2"},
        "unknown suite");
  check({"eval", "--config", cfg, "--agent", "bc-oh", "--out", dir / "o3"}, "--checkpoint");
  check({"eval", "--config", cfg, "--agent", "bc-oh", "--checkpoint", dir / "missing", "--out",
         dir / "o4"},
        "missing");
  // A folder holding another agent's run is not overwritten.
  auto r = eval_cli(cfg, "quickstart", dir / "o5");
  ASSERT_EQ(r.exit_code, 0) << r.describe();
  const std::string before = test::read_text(dir / "o5/results.json");
  check({"eval", "--config", cfg, "--agent", "cs", "--out", dir / "o5"}, "another evaluation");
  EXPECT_EQ(test::read_text(dir / "o5/results.json"), before);
}

}  // namespace
}  // namespace cd

namespace cd {
namespace {

// A learned agent end to end: collect, train a tiny bc-oh, evaluate it twice (different
// worker counts): the runner feeds it real-frame histories and the results are reproducible.
TEST(BenchEval, LearnedAgentEvaluatesReproducibly) {
  TempDir dir("cdtest-eval");
  const std::string cfg = test::write_test_config(
      dir, "regular", "\n[train]\nepochs = 1\nmax_samples = 300\nthreads = 1\n"
                      "\n[model]\naction_head = \"target_speed\"\n");
  auto c = test::run_cli({"collect", "--config", cfg, "--out", dir / "data"});
  ASSERT_EQ(c.exit_code, 0) << c.describe();
  auto t = test::run_cli({"train", "--config", cfg, "--method", "bc-oh", "--data", dir / "data",
                          "--out", dir / "ckpt"});
  ASSERT_EQ(t.exit_code, 0) << t.describe();
  std::vector<std::string> args = {"eval", "--config", cfg, "--agent", "bc-oh", "--checkpoint",
                                   dir / "ckpt", "--suite", "quickstart", "--quiet"};
  auto run = [&](const std::string& out, const std::string& workers) {
    std::vector<std::string> a = args;
    a.insert(a.end(), {"--out", out, "--workers", workers});
    return test::run_cli(a);
  };
  auto a = run(dir / "a", "1");
  auto b = run(dir / "b", "2");
  ASSERT_EQ(a.exit_code, 0) << a.describe();
  ASSERT_EQ(b.exit_code, 0) << b.describe();
  nlohmann::json res = read_json(dir / "a/results.json");
  EXPECT_EQ(res["agent"], "bc-oh");
  EXPECT_EQ(res["summary"]["episodes"], 4);
  EXPECT_EQ(res["summary"]["infrastructure_failures"], 0);
  EXPECT_EQ(test::read_text(dir / "a/results.json"), test::read_text(dir / "b/results.json"));
}

}  // namespace
}  // namespace cd
