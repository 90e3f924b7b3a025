// `causaldrive train --method M` on a MuJoCo-Image collect folder and `causaldrive eval --env`:
// a tiny halfcheetah folder (2 episodes x 20 steps, a cheap planner), bc-oh and residual trained
// one epoch each, one short closed-loop episode of each; results.json's keys, same seed same
// bytes, and the one-line errors (a driving checkpoint, another env's action size, dagger).
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include <string>
#include <vector>

#include "../support/fake_episodes.hpp"
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
  EXPECT_EQ(ck["settings"]["model"]["speed_loss_weight"], 0.0);
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
      test::run_cli({"train", "--method", "dagger", "--data", *dir_ / "data", "--out",
                     *dir_ / "run_dagger"}),
      "dagger on MuJoCo-Image data is not supported");
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

}  // namespace
}  // namespace cd
