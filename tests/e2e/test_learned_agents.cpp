// Learned agents end to end through the binary, on tiny runs (tests/support/tiny_run.hpp):
// collect two short episodes, train the method, write a one-task suite, evaluate the agent in
// the simulator: bc-oh (reproducible whatever the worker count), dim (its plan moves the ego),
// cim.
#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include <nlohmann/json.hpp>

#include "../support/tiny_run.hpp"

namespace cd {
namespace {

using nlohmann::json;

// The runner feeds a learned agent real-frame histories, and its results are reproducible:
// evaluated twice with different worker counts, the bytes are the same.
TEST(BenchEval, LearnedAgentEvaluatesReproducibly) {
  test::TinyRun run({.method = "bc-oh",
                     .traffic = "regular",
                     .extra = "\n[train]\nepochs = 1\nmax_samples = 300\nthreads = 1\n"
                              "\n[model]\naction_head = \"target_speed\"\n"});
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
}

// A tiny cim (beta-VAE, Granger selection, speed predictor) drives its own target speeds on a
// leader task; the results have the contract keys.
TEST(CimEval, TinyRunDrivesInTheSimulator) {
  test::TinyRun run({.method = "cim",
                     .traffic = "regular",
                     .extra = "\n[vae]\nlatents = 16\nepochs = 1\nmax_frames = 300\n"
                              "\n[cim]\nepochs = 1\nmax_causes = 2\n\n[train]\nthreads = 1\n",
                     .suite = {.traffic = "regular", .scenarios = {"leader"}}});
  auto e = run.eval("eval");
  EXPECT_NE(e.out.find("| cim |"), std::string::npos) << e.out;
  json res = run.results("eval");
  EXPECT_EQ(res["agent"], "cim");
  ASSERT_EQ(res["episodes"].size(), 1u);
  EXPECT_EQ(res["summary"]["infrastructure_failures"], 0);
  const std::string outcome = res["episodes"][0]["outcome"];
  EXPECT_TRUE(outcome == "success" || outcome == "collision" || outcome == "timeout" ||
              outcome == "inertia")
      << outcome;
}

}  // namespace
}  // namespace cd
