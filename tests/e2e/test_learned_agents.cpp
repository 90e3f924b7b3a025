// Learned agents end to end through the binary, on tiny runs (tests/support/tiny_run.hpp):
// collect two episodes, train the method, write a one-task suite, evaluate the agent in the
// simulator. bc-oh (reproducible whatever the worker count), dim (its plan moves the ego) and
// cim (it drives to its goal, with consistent and reproducible results).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <string>

#include <nlohmann/json.hpp>

#include "../support/tiny_run.hpp"

namespace cd {
namespace {

using nlohmann::json;

// The runner feeds a learned agent real-frame histories, and its results are reproducible:
// evaluated twice with different worker counts, the bytes are the same.
TEST(BenchEval, LearnedAgentEvaluatesReproducibly) {
  CD_NEEDS_SUMO();
  test::TinyRun run({.method = "bc-oh",
                     .traffic = "regular",
                     .extra = "\n[train]\nepochs = 1\nmax_samples = 300\nthreads = 1\n"
                              "\n[model]\naction_head = \"target_speed\"\n"
                              "\n[ego]\nlateral = \"route\"\n"});  // a target speed: no steer
  run.eval("a", 1, "quickstart");
  run.eval("b", 2, "quickstart");
  json res = run.results("a");
  EXPECT_EQ(res["agent"], "bc-oh");
  EXPECT_EQ(res["summary"]["episodes"], 4);
  EXPECT_EQ(res["summary"]["infrastructure_failures"], 0);
  EXPECT_EQ(test::read_text(run.dir() / "a/results.json"),
            test::read_text(run.dir() / "b/results.json"));
}

TEST(DimCli, TrainsAndDrivesInTheSimulator) {
  CD_NEEDS_SUMO();
  test::TinyRun run({.method = "dim",
                     .traffic = "empty",
                     .extra = "\n[train]\nepochs = 1\nmax_samples = 400\nthreads = 1\n"
                              "batch_size = 32\n"
                              "\n[dim]\nfeatures = 32\nhidden = 32\nplan_iterations = 10\n",
                     .suite = {.traffic = "empty", .scenarios = {"route"}}});
  auto e = run.eval("eval");
  EXPECT_NE(e.out.find("| dim |"), std::string::npos) << e.out;
  json res = run.results("eval");
  EXPECT_EQ(res["agent"], "dim");
  ASSERT_EQ(res["episodes"].size(), 1u);
  EXPECT_EQ(res["summary"]["infrastructure_failures"], 0);
  // It moved: the plan's speed reached the vehicle.
  EXPECT_GT(res["episodes"][0]["route_completion"].get<double>(), 0.0) << res.dump();
  // How far the planner moved its plans: one plan every replan_steps (2) agent steps; the
  // best iterate is kept, so the objective never falls; the summary holds the episode means.
  const json& a = res["episodes"][0]["agent"];
  ASSERT_TRUE(a.is_object()) << res["episodes"][0].dump();
  EXPECT_GT(a["plans"].get<double>(), 0.0);
  EXPECT_GE(a["plan_objective_gain"].get<double>(), 0.0);
  EXPECT_GE(a["plans_improved"].get<double>(), 0.0);
  EXPECT_LE(a["plans_improved"].get<double>(), 1.0);
  EXPECT_GE(a["plan_moved_m"].get<double>(), 0.0);
  EXPECT_EQ(res["summary"]["agent"], a);
  // Without ascent steps the plan is the initial guess: no gain, nothing moved.
  const std::string still = run.dir() / "still.toml";
  std::string text = test::read_text(run.config());
  text.replace(text.find("plan_iterations = 10"), 20, "plan_iterations = 0");
  test::write_text(still, text);
  test::run_cli_ok(test::eval_args(still, "dim", run.run(), run.suite(), run.dir() / "still", 1));
  const json s = run.results("still")["episodes"][0]["agent"];
  EXPECT_GT(s["plans"].get<double>(), 0.0);
  EXPECT_EQ(s["plan_objective_gain"].get<double>(), 0.0);
  EXPECT_EQ(s["plans_improved"].get<double>(), 0.0);
  EXPECT_EQ(s["plan_moved_m"].get<double>(), 0.0);
}

// A tiny cim (beta-VAE, Granger selection, speed predictor) drives its own target speeds on an
// empty road. What a working agent does here, deterministically: it moves and reaches its goal
// (an agent that never moves, or outputs NaN, does not); its episode's figures agree with each
// other and with the summary; the same run evaluated again gives the same bytes. (On a short
// route the expert waits at red lights most of the time and the predictor's L1 fit is a
// median speed of 0, so the tiny run records longer routes, where the expert mostly drives.)
// A free-steering ego (ego.lateral = "free"): a family policy trained on its (throttle, brake,
// steer) data and dim (steering along its plan) are accepted and drive; their episodes record
// the lateral error. A policy trained without steer is refused there with one line.
TEST(SteeringAgents, TrainedOnSteeringDataTheyDriveAFreeEgo) {
  CD_NEEDS_SUMO();
  const std::string free = "\n[ego]\nlateral = \"free\"\n";
  const std::string route = "\n[ego]\nlateral = \"route\"\n";
  test::TinyRun bc({.method = "bc-so",
                    .traffic = "empty",
                    .extra = free + "\n[train]\nepochs = 1\nmax_samples = 300\nthreads = 1\n",
                    .suite = {.traffic = "empty", .scenarios = {"route"}}});
  EXPECT_EQ(test::read_json(bc.run() + "/checkpoint.json")["input"]["action_output"], "tanh")
      << "the default signed pedals: throttle - brake in [-1, 1], then steer in [-1, 1]";
  bc.eval("eval");
  json res = bc.results("eval");
  ASSERT_EQ(res["episodes"].size(), 1u);
  EXPECT_EQ(res["summary"]["infrastructure_failures"], 0);
  EXPECT_TRUE(res["episodes"][0].contains("lateral_error_m")) << res.dump();
  test::TinyRun dim({.method = "dim",
                     .traffic = "empty",
                     .extra = free + "\n[train]\nepochs = 1\nmax_samples = 400\nthreads = 1\n"
                                     "batch_size = 32\n"
                                     "\n[dim]\nfeatures = 32\nhidden = 32\nplan_iterations = 10\n",
                     .suite = {.traffic = "empty", .scenarios = {"route"}}});
  dim.eval("eval");
  res = dim.results("eval");
  ASSERT_EQ(res["episodes"].size(), 1u);
  EXPECT_EQ(res["summary"]["infrastructure_failures"], 0);
  EXPECT_TRUE(res["episodes"][0].contains("lateral_error_m")) << res.dump();
  EXPECT_GT(res["episodes"][0]["agent"]["plans"].get<double>(), 0.0);

  // cim steers along that dim's planned path (eval.cim_path) at its own causal speed: the dim
  // agent plans inside cim's episodes (its planner figures are cim's), and a route-mode ego,
  // which does not steer, refuses the key in one line.
  test::TinyRun cim({.method = "cim",
                     .traffic = "empty",
                     .extra = free + "\n[vae]\nlatents = 16\nepochs = 1\nmax_frames = 300\n"
                                     "\n[cim]\nmax_causes = 2\n\n[train]\nthreads = 1\n",
                     .suite = {.traffic = "empty", .scenarios = {"route"}}});
  const std::string with_path = "\n[eval]\ncim_path = \"" + dim.run() + "\"\n";
  const std::string path_config =
      test::write_test_config(cim.dir(), "empty", free + with_path, "path.toml");
  test::CommandResult r = test::run_cli(
      test::eval_args(path_config, "cim", cim.run(), cim.suite(), cim.dir() / "path", 1));
  ASSERT_TRUE(r.exited && r.exit_code == 0) << r.describe();
  res = json::parse(test::read_text(cim.dir() / "path/results.json"));
  ASSERT_EQ(res["episodes"].size(), 1u);
  EXPECT_EQ(res["summary"]["infrastructure_failures"], 0);
  EXPECT_TRUE(res["episodes"][0].contains("lateral_error_m")) << res.dump();
  EXPECT_GT(res["episodes"][0]["agent"]["plans"].get<double>(), 0.0) << res.dump();
  const std::string route_config =
      test::write_test_config(cim.dir(), "empty", route + with_path, "route.toml");
  cim.refused_eval(route_config, "route", "needs ego.lateral");
  // --cim-path sets the key; a folder without a dim/rip run is refused in one line.
  cim.refused_eval(cim.config(), "bad", "holds no dim/rip run", {"--cim-path", bc.run()});
}

TEST(SteeringAgents, APolicyTrainedWithoutSteerIsRefusedOnAFreeEgo) {
  CD_NEEDS_SUMO();
  test::TinyRun route({.method = "bc-so",
                       .traffic = "empty",
                       .extra = "\n[ego]\nlateral = \"route\"\n"
                                "\n[train]\nepochs = 1\nmax_samples = 200\nthreads = 1\n",
                       .suite = {.traffic = "empty", .scenarios = {"route"}}});
  const std::string free_config = test::write_test_config(
      route.dir(), "empty", "\n[ego]\nlateral = \"free\"\n", "free.toml");
  route.refused_eval(free_config, "free", "trained without steer");
}

TEST(CimEval, TinyRunDrivesInTheSimulator) {
  CD_NEEDS_SUMO();
  test::TinyRun run({.method = "cim",
                     .traffic = "empty",
                     .extra = "\n[vae]\nlatents = 16\nepochs = 1\nmax_frames = 300\n"
                              "\n[cim]\nmax_causes = 2\n\n[train]\nthreads = 1\n",
                     .suite = {.traffic = "empty", .scenarios = {"route"}},
                     .min_route_m = 400,
                     .max_route_m = 700});
  auto e = run.eval("eval");
  EXPECT_NE(e.out.find("| cim |"), std::string::npos) << e.out;
  const json res = run.results("eval");
  EXPECT_EQ(res["agent"], "cim");
  ASSERT_EQ(res["episodes"].size(), 1u);
  const json& ep = res["episodes"][0];
  const json& sum = res["summary"];
  EXPECT_EQ(sum["infrastructure_failures"], 0);
  EXPECT_EQ(sum["episodes"], 1);

  // It drove to its goal.
  const double length = ep["route_length_m"], distance = ep["distance_m"];
  const double completion = ep["route_completion"], duration = ep["duration_s"];
  const double speed = ep["mean_speed"];
  EXPECT_EQ(ep["outcome"].get<std::string>(), "success") << ep.dump();
  EXPECT_GT(length, 0.0);
  EXPECT_GE(distance, length - 1.0) << ep.dump();
  EXPECT_DOUBLE_EQ(completion, 1.0) << ep.dump();
  EXPECT_GT(speed, 1.0) << ep.dump();
  // Its figures agree: mean speed is distance over time, within the task's timeout (the
  // route at 5 km/h plus 20 s).
  EXPECT_GT(duration, 0.0);
  EXPECT_LE(duration, length / (5.0 / 3.6) + 20.0 + 1e-6);
  EXPECT_NEAR(speed, distance / duration, 1e-9 * std::max(1.0, speed)) << ep.dump();

  // The summary is that one episode's.
  for (const char* o : {"success", "collision", "offroad", "stuck", "restart_stall",
                        "stopped_free", "blocked", "slow"})
    EXPECT_DOUBLE_EQ(sum[std::string(o) + "_rate"].get<double>(), ep["outcome"] == o ? 1.0 : 0.0)
        << o;
  EXPECT_DOUBLE_EQ(sum["route_completion"].get<double>(), completion);
  EXPECT_DOUBLE_EQ(sum["mean_speed"].get<double>(), speed);
  EXPECT_DOUBLE_EQ(sum["distance_km"].get<double>(), distance / 1000.0);

  // The same run evaluated again: the same bytes.
  run.eval("again");
  EXPECT_EQ(test::read_text(run.dir() / "again/results.json"),
            test::read_text(run.dir() / "eval/results.json"));
}

}  // namespace
}  // namespace cd
