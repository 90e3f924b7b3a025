// `causaldrive train --method M` on a MuJoCo-Image collect folder and `causaldrive eval --env`:
// a tiny halfcheetah folder (2 episodes x 20 steps, a cheap planner), bc-oh and residual trained
// one epoch each, one short closed-loop episode of each; results.json's keys, same seed same
// bytes, and the one-line errors (a driving checkpoint, another env's action size); dagger's
// rounds in the env (expert labels at every state, the policy acting once its history is
// real); collect --env and eval --env from a config's [mujoco] table; report's return table
// against the mean and sd computed by hand.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdio>
#include <string>
#include <algorithm>
#include <vector>

#include "../support/fake_episodes.hpp"
#include "core/rng.hpp"
#include "data/mujoco_episode.hpp"
#include "mujoco/expert.hpp"
#include "../support/test_support.hpp"
#include "../support/tiny_run.hpp"

namespace cd {
namespace {

using test::TempDir;

class MujocoTrainEval : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new TempDir("cdtest-mjtrain");
    test::run_cli_ok({"collect", "--env", "halfcheetah", "--episodes", "2", "--max-steps", "20",
                      "--planner-samples", "8", "--planner-horizon", "4", "--size", "32",
                      "--out", *dir_ / "data"});
    for (const char* m : {"bc-oh", "residual"})
      test::run_cli_ok({"train", "--method", m, "--data", *dir_ / "data", "--out",
                        *dir_ / (std::string("run_") + m), "--epochs", "1", "--threads", "1"});
  }
  static void TearDownTestSuite() {
    delete dir_;
    dir_ = nullptr;
  }
  static std::vector<std::string> eval(const std::string& agent, const std::string& out,
                                       const std::string& env = "halfcheetah") {
    std::vector<std::string> a = {"eval", "--env", env, "--agent", agent, "--episodes", "1",
                                  "--max-steps", "12", "--seed", "4", "--out", *dir_ / out,
                                  "--quiet"};
    if (agent != "expert" && agent != "random")
      a.insert(a.end(), {"--checkpoint", *dir_ / ("run_" + agent)});
    return a;
  }
  static TempDir* dir_;
};

TempDir* MujocoTrainEval::dir_ = nullptr;

TEST_F(MujocoTrainEval, CheckpointRecordsTheDomainAndTanh) {
  const nlohmann::json ck = test::read_json(*dir_ / "run_residual/checkpoint.json");
  EXPECT_EQ(ck["input"]["domain"], "mujoco");
  EXPECT_EQ(ck["input"]["env"], "halfcheetah");
  EXPECT_EQ(ck["input"]["action_dim"], 6);
  EXPECT_EQ(ck["input"]["channels"], 3);
  EXPECT_EQ(ck["input"]["action_output"], "tanh") << "actions in [-1, 1]";
  EXPECT_EQ(ck["settings"]["model"]["speed_loss_weight"], 0.0);
}

// The copycat probe draws a driving scene's moving history; MuJoCo-Image's frames have none,
// and are refused in one line.
TEST_F(MujocoTrainEval, TheCopycatProbeRefusesMujocoFrames) {
  test::expect_one_line_error(
      test::run_cli({"probe", "--checkpoint", *dir_ / "run_bc-oh", "--data", *dir_ / "data"}),
      "holds MuJoCo-Image frames (not supported)");
}

TEST_F(MujocoTrainEval, EvalWritesResultsAndIsSeeded) {
  for (const char* m : {"bc-oh", "residual"}) {
    const std::string out = std::string("eval_") + m;
    test::run_cli_ok(eval(m, out));
    const nlohmann::json r = test::read_json(*dir_ / (out + "/results.json"));
    EXPECT_EQ(r["agent"], m);
    EXPECT_EQ(r["env"], "halfcheetah");
    ASSERT_EQ(r["episodes"].size(), 1u);
    EXPECT_EQ(r["episodes"][0]["length"], 12);
    EXPECT_TRUE(r["episodes"][0]["return"].is_number());
    for (const char* k : {"mean_return", "std_return", "mean_length"})
      EXPECT_TRUE(r["summary"][k].is_number()) << k;
    EXPECT_TRUE(r["copycat"].contains("policy_r2"));
    EXPECT_TRUE(r["copycat"]["expert_data_r2"].is_number());
  }
  test::run_cli_ok(eval("bc-oh", "eval_again"));
  EXPECT_EQ(test::read_text(*dir_ / "eval_bc-oh/results.json"),
            test::read_text(*dir_ / "eval_again/results.json"));
  // A rerun into the same folder resumes (nothing left to run) and keeps the bytes.
  const std::string before = test::read_text(*dir_ / "eval_bc-oh/results.json");
  test::run_cli_ok(eval("bc-oh", "eval_bc-oh"));
  EXPECT_EQ(before, test::read_text(*dir_ / "eval_bc-oh/results.json"));
}

// Batched inference (eval.batch = "on"): three worlds served by one inference process give
// the bytes of one world running its network itself.
TEST_F(MujocoTrainEval, ServedWorldsGiveTheBytesOfOneWorld) {
  for (const char* batch : {"on", "off"}) {
    const std::string cfg = *dir_ / (std::string("batch-") + batch + ".toml");
    test::write_text(cfg, std::string("[eval]\nbatch = \"") + batch + "\"\n");
    for (const char* workers : {"1", "3"}) {
      std::vector<std::string> a = eval("residual", std::string("served_") + batch + workers);
      a.insert(a.end(), {"--config", cfg, "--workers", workers});
      a[std::find(a.begin(), a.end(), "--episodes") - a.begin() + 1] = "3";
      test::run_cli_ok(a);
    }
  }
  const std::string one = test::read_text(*dir_ / "served_off1/results.json");
  EXPECT_EQ(test::read_json(*dir_ / "served_off1/results.json")["episodes"].size(), 3u);
  for (const char* other : {"served_on3", "served_on1", "served_off3"})
    EXPECT_EQ(test::read_text(*dir_ / (std::string(other) + "/results.json")), one) << other;
}

TEST_F(MujocoTrainEval, RandomAgentHasNoExpertData) {
  test::run_cli_ok(eval("random", "eval_random"));
  const nlohmann::json r = test::read_json(*dir_ / "eval_random/results.json");
  EXPECT_TRUE(r["copycat"]["expert_data_r2"].is_null());
  EXPECT_EQ(r["summary"]["mean_length"], 12.0);
}

TEST_F(MujocoTrainEval, OneLineErrors) {
  test::expect_one_line_error(test::run_cli(eval("bc-oh", "eval_hopper", "hopper")),
                              "6 actions");
  test::expect_one_line_error(
      test::run_cli({"eval", "--env", "halfcheetah", "--agent", "expert", "--suite",
                     "town-a-regular", "--out", *dir_ / "eval_suite"}),
      "--suite is a driving option");
  // A driving checkpoint.
  test::write_fake_folder(*dir_ / "drive", 2, {.frames = 12, .channels = 2, .height = 16,
                                               .width = 16});
  test::run_cli_ok({"train", "--method", "bc-oh", "--data", *dir_ / "drive", "--out",
                    *dir_ / "run_drive", "--epochs", "1", "--threads", "1"});
  std::vector<std::string> a = eval("bc-oh", "eval_drive");
  a.back() = "--quiet";
  for (size_t i = 0; i + 1 < a.size(); ++i)
    if (a[i] == "--checkpoint") a[i + 1] = *dir_ / "run_drive";
  test::expect_one_line_error(test::run_cli(a), "trained on driving data");
}

// A config's [mujoco] table sets collect's episode count for the env and eval's episodes.
TEST_F(MujocoTrainEval, ConfigTableSetsCountsAndFlagsOverride) {
  const std::string cfg = *dir_ / "mj.toml";
  test::write_text(cfg,
                   "[mujoco]\nsize = 16\nmax_steps = 6\nworkers = 1\neval_episodes = 2\n"
                   "planner_samples = 4\nplanner_horizon = 3\n"
                   "[mujoco.episodes]\nreacher = 3\n");
  test::run_cli_ok({"collect", "--env", "reacher", "--config", cfg, "--out", *dir_ / "cfg_data"});
  const nlohmann::json c = test::read_json(*dir_ / "cfg_data/collect.json");
  EXPECT_EQ(c["episodes"].size(), 3u);
  EXPECT_EQ(c["width"], 16);
  EXPECT_EQ(c["max_steps"], 6);
  test::run_cli_ok({"collect", "--env", "reacher", "--config", cfg, "--episodes", "1",
                    "--out", *dir_ / "cfg_data1"});
  EXPECT_EQ(test::read_json(*dir_ / "cfg_data1/collect.json")["episodes"].size(), 1u);
  test::run_cli_ok({"eval", "--env", "reacher", "--config", cfg, "--agent", "random", "--out",
                    *dir_ / "cfg_eval", "--quiet"});
  const nlohmann::json r = test::read_json(*dir_ / "cfg_eval/results.json");
  EXPECT_EQ(r["episodes"].size(), 2u);
  EXPECT_EQ(r["summary"]["mean_length"], 6.0);
  test::write_text(*dir_ / "bad.toml", "[mujoco]\nframes = 3\n");
  test::expect_one_line_error(
      test::run_cli({"collect", "--env", "reacher", "--config", *dir_ / "bad.toml", "--out",
                     *dir_ / "bad_data"}),
      "mujoco.frames");
}

// report on eval --env folders: rows by label, columns by env, mean and sample sd over seeds.
TEST_F(MujocoTrainEval, ReportAveragesReturnsOverSeeds) {
  std::vector<double> means;
  for (const char* seed : {"1", "2", "3"}) {
    const std::string out = *dir_ / (std::string("rep/random_s") + seed);
    test::run_cli_ok({"eval", "--env", "halfcheetah", "--agent", "random", "--label", "rnd",
                      "--episodes", "2", "--max-steps", "5", "--seed", seed, "--out", out,
                      "--quiet"});
    means.push_back(test::read_json(out + "/results.json")["summary"]["mean_return"].get<double>());
  }
  const double m = (means[0] + means[1] + means[2]) / 3;
  double var = 0;
  for (double v : means) var += (v - m) * (v - m) / 2;
  test::run_cli_ok({"report", *dir_ / "rep", "--csv", *dir_ / "rep.csv"});
  const std::string csv = test::read_text(*dir_ / "rep.csv");
  const std::string key = "rnd,halfcheetah,mean_return,";
  const size_t at = csv.find(key);
  ASSERT_NE(at, std::string::npos) << csv;
  double mean = 0, sd = 0;
  int n = 0;
  ASSERT_EQ(std::sscanf(csv.c_str() + at + key.size(), "%lf,%lf,%d", &mean, &sd, &n), 3) << csv;
  EXPECT_NEAR(mean, m, 1e-6 * (1 + std::abs(m)));
  EXPECT_NEAR(sd, std::sqrt(var), 1e-6 * (1 + std::sqrt(var)));
  EXPECT_EQ(n, 3);
}

// dagger in the env: iteration 0 is bc-oh on the data; round 1 drives 2 episodes of 10 steps
// mixing the planner with the policy and records the planner's label at every state.
TEST_F(MujocoTrainEval, DaggerAggregatesExpertLabelsFromTheEnv) {
  const std::string cfg = *dir_ / "dagger.toml";
  test::write_text(cfg,
                   "[train]\nepochs = 1\nthreads = 1\n"
                   "[dagger]\niterations = 1\nepisodes = 2\nepochs = 1\nbeta = 0.5\n"
                   "[mujoco]\nmax_steps = 10\nworkers = 1\nplanner_samples = 8\n"
                   "planner_horizon = 4\n");
  test::run_cli_ok({"train", "--config", cfg, "--method", "dagger", "--data", *dir_ / "data",
                    "--out", *dir_ / "run_dagger"});
  const nlohmann::json d = test::read_json(*dir_ / "run_dagger/dagger.json");
  ASSERT_EQ(d["iterations"].size(), 1u);
  EXPECT_EQ(d["iterations"][0]["expert_labels"], 20);  // halfcheetah never terminates
  EXPECT_EQ(d["expert_labels"], 20);
  const nlohmann::json ck = test::read_json(*dir_ / "run_dagger/checkpoint.json");
  EXPECT_EQ(ck["method"], "dagger");
  EXPECT_EQ(ck["input"]["domain"], "mujoco");
  // The rollouts' rows: the planner's label everywhere; the policy executed (noise = 1) only
  // once the history holds real frames ((K - 1) * stride steps), and sometimes.
  const int K = ck["input"]["history"], stride = ck["input"]["stride"];
  const int prefill = (K - 1) * stride;
  int policy_steps = 0;
  for (const char* f : {"episode_000000.h5", "episode_000001.h5"}) {
    const MujocoEpisode e = read_mujoco_episode(*dir_ / (std::string("run_dagger/rollouts_01/") + f));
    ASSERT_EQ(e.frames(), 10u);
    // The labels are the planner's answers at the recorded states, asked in order (its warm
    // start makes each answer depend on the ones before) with the episode's planner seed; the
    // file keeps the state in float32, hence the tolerance (another action is ~0.3 away).
    mj::PlannerOptions po;
    po.samples = 8;
    po.horizon = 4;
    po.seed = derive_seed(e.seed, 1);
    mj::PlannerExpert planner("halfcheetah", po);
    const size_t S = static_cast<size_t>(e.state_dim), A = static_cast<size_t>(e.action_dim);
    for (size_t t = 0; t < e.frames(); ++t) {
      const std::vector<double> state(e.state.begin() + t * S, e.state.begin() + (t + 1) * S);
      const std::vector<double> label = planner.act(state);
      for (size_t j = 0; j < A; ++j)
        ASSERT_NEAR(e.action[t * A + j], label[j], 1e-3) << f << " t " << t;
      if (static_cast<int>(t) < prefill) {
        EXPECT_EQ(e.noise[t], 0) << "the expert fills the history";
      }
      policy_steps += e.noise[t];
    }
  }
  EXPECT_GT(policy_steps, 0) << "the policy never acted";
  EXPECT_LT(policy_steps, 2 * (10 - prefill)) << "beta 0.5: the expert acts too";
  // It drives: eval --agent dagger runs the aggregated policy.
  test::run_cli_ok(eval("dagger", "eval_dagger"));
  EXPECT_EQ(test::read_json(*dir_ / "eval_dagger/results.json")["episodes"][0]["length"], 12);
}

}  // namespace
}  // namespace cd
