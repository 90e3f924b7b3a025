// `causaldrive collect --env`: the MuJoCo-Image domain from the command line (one tiny run),
// its one-line errors, and the driving options it refuses; `bench env` and `bench expert` (their
// JSON: keys and sane values, never timings).
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include <string>
#include <vector>

#include "../support/test_support.hpp"
#include "data/mujoco_episode.hpp"

namespace cd {
namespace {

using test::CommandResult;
using test::TempDir;

std::string one_line_error(const CommandResult& r, const std::string& what) {
  EXPECT_TRUE(r.exited) << what << ": " << r.describe();
  EXPECT_EQ(r.exit_code, 1) << what << ": " << r.describe();
  const std::vector<std::string> lines = test::split_lines(r.err);
  EXPECT_EQ(lines.size(), 1u) << what << ": stderr should be one line:\n" << r.err;
  return lines.empty() ? "" : lines.front();
}

bool has(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

TEST(CliMujoco, UnknownEnvIsOneLine) {
  CD_NEEDS_MUJOCO();
  TempDir dir("cdtest-mjcli");
  const std::string line = one_line_error(
      test::run_cli({"collect", "--env", "cheetah", "--out", dir / "data"}), "unknown env");
  EXPECT_TRUE(has(line, "unknown MuJoCo environment 'cheetah'")) << line;
  EXPECT_FALSE(test::fs::exists(dir / "data"));
}

TEST(CliMujoco, MissingModelFileIsOneLine) {
  CD_NEEDS_MUJOCO();
  TempDir dir("cdtest-mjcli");
  test::ScopedEnv assets("CAUSALDRIVE_MUJOCO_ASSETS", dir / "nowhere");
  const std::string line = one_line_error(
      test::run_cli({"collect", "--env", "hopper", "--out", dir / "data"}), "missing model");
  EXPECT_TRUE(has(line, dir / "nowhere/hopper.xml")) << line;
}

TEST(CliMujoco, DrivingOptionsAreRefusedWithEnv) {
  TempDir dir("cdtest-mjcli");
  const std::string line = one_line_error(
      test::run_cli({"collect", "--env", "hopper", "--town", "town-a", "--out", dir / "data"}),
      "--town with --env");
  EXPECT_TRUE(has(line, "--town")) << line;
}

TEST(CliMujoco, CollectsATinyDatasetAndResumes) {
  CD_NEEDS_MUJOCO();
  TempDir dir("cdtest-mjcli");
  const std::vector<std::string> args = {"collect", "--env", "reacher", "--episodes", "1",
                                         "--max-steps", "3", "--planner-samples", "4",
                                         "--planner-horizon", "2", "--workers", "1", "--out",
                                         dir / "data"};
  CommandResult r = test::run_cli(args);
  ASSERT_EQ(r.exit_code, 0) << r.describe();
  EXPECT_TRUE(test::fs::exists(dir / "data/episode_000000.h5"));
  EXPECT_TRUE(has(r.out, "recorded now: 1")) << r.out;
  r = test::run_cli(args);
  ASSERT_EQ(r.exit_code, 0) << r.describe();
  EXPECT_TRUE(has(r.out, "recorded now: 0")) << r.out;
  // The planner's other settings reach the expert the file records.
  std::vector<std::string> tuned = args;
  tuned.back() = dir / "tuned";
  for (const char* a : {"--planner-iterations", "3", "--planner-sigma", "0.25",
                        "--planner-temperature", "0.2", "--planner-smoothing", "0.5"})
    tuned.push_back(a);
  r = test::run_cli(tuned);
  ASSERT_EQ(r.exit_code, 0) << r.describe();
  const MujocoEpisode m = read_mujoco_episode_meta(dir / "tuned/episode_000000.h5");
  EXPECT_TRUE(has(m.extra.at("expert"), "iterations=3 sigma=0.25 temperature=0.2 smoothing=0.5"))
      << m.extra.at("expert");
  tuned.push_back("--planner-smoothing");
  tuned.push_back("1.5");
  EXPECT_NE(test::run_cli(tuned).exit_code, 0);
}

TEST(CliMujoco, BenchEnvJsonHasPhysicsRenderAndEverySize) {
  CD_NEEDS_MUJOCO();
  const CommandResult r =
      test::run_cli({"bench", "env", "--env", "hopper", "--steps", "40", "--slices", "2",
                     "--size", "16,24", "--expert-steps", "1", "--json"});
  ASSERT_EQ(r.exit_code, 0) << r.describe();
  const std::vector<std::string> lines = test::split_lines(r.out);
  ASSERT_EQ(lines.size(), 1u) << r.out;
  const nlohmann::json j = nlohmann::json::parse(lines[0]);
  EXPECT_EQ(j["env"], "hopper");
  EXPECT_EQ(j["size"], 16) << "the top-level figures are the first size's";
  EXPECT_EQ(j["steps"], 40);
  EXPECT_EQ(j["slices"], 2);
  for (const char* k : {"physics_steps_per_s", "full_steps_per_s", "expert_steps_per_s"}) {
    ASSERT_TRUE(j[k].is_number()) << k;
    EXPECT_GT(j[k].get<double>(), 0.0) << k;
  }
  // Rendering costs something, never more than the whole step.
  EXPECT_LT(j["render_share"].get<double>(), 1.0);
  EXPECT_EQ(j["expert_steps"], 2);  // one per slice
  ASSERT_EQ(j["sizes"].size(), 2u);
  EXPECT_EQ(j["sizes"][1]["size"], 24);
  EXPECT_GT(j["sizes"][1]["full_steps_per_s"].get<double>(), 0.0);
}

TEST(CliMujoco, BenchEnvUnknownEnvIsOneLine) {
  CD_NEEDS_MUJOCO();
  const std::string line =
      one_line_error(test::run_cli({"bench", "env", "--env", "walker", "--json"}), "bench env");
  EXPECT_TRUE(has(line, "unknown MuJoCo environment 'walker'")) << line;
}

TEST(CliMujoco, BenchExpertReportsReturnAndCostAndIsSeeded) {
  CD_NEEDS_MUJOCO();
  const std::vector<std::string> args = {"bench", "expert", "--env", "reacher", "--steps", "3",
                                         "--samples", "4", "--horizon", "2", "--seed", "7",
                                         "--json"};
  const CommandResult r = test::run_cli(args);
  ASSERT_EQ(r.exit_code, 0) << r.describe();
  const nlohmann::json j = nlohmann::json::parse(test::split_lines(r.out).at(0));
  EXPECT_EQ(j["env"], "reacher");
  EXPECT_EQ(j["steps"], 3);
  EXPECT_EQ(j["terminated"], false);
  EXPECT_LT(j["return"].get<double>(), 0.0) << "reacher's reward is a negative distance";
  EXPECT_EQ(j["simulated_steps"], 3 * 4 * 2 * 2) << "reacher's default: 2 iterations";
  EXPECT_GT(j["s_per_step"].get<double>(), 0.0);
  // 2 pairs of consecutive 2-d actions cannot fit a_t ~ W a_{t-1} + b: undefined, null.
  ASSERT_TRUE(j.contains("action_lag1_r2"));
  EXPECT_TRUE(j["action_lag1_r2"].is_null());
  const CommandResult again = test::run_cli(args);
  EXPECT_EQ(nlohmann::json::parse(test::split_lines(again.out).at(0))["return"], j["return"]);
}

// train-expert writes a policy and its record; a config naming the folder makes it collect's
// expert (the file says so, and the labels are its deterministic actions: the same on a rerun
// into another folder); a folder without the env's policy is one line naming the file.
TEST(CliMujoco, TrainExpertThenCollectWithIt) {
  CD_NEEDS_MUJOCO();
  TempDir dir("cdtest-mjcli");
  CommandResult r = test::run_cli({"train-expert", "--env", "reacher", "--out",
                                   dir / "experts/reacher.pt", "--steps", "300", "--start-steps",
                                   "150", "--batch", "16", "--hidden", "8", "--eval-every", "150",
                                   "--eval-episodes", "1"});
  ASSERT_EQ(r.exit_code, 0) << r.describe();
  EXPECT_TRUE(has(r.out, "best return")) << r.out;
  const auto record = nlohmann::json::parse(test::read_text(dir / "experts/reacher.json"));
  EXPECT_EQ(record["env"], "reacher");
  EXPECT_EQ(record["evaluations"].size(), 2u);

  const std::string cfg = dir / "mj.toml";
  test::write_text(cfg, "[mujoco]\nexpert_policies = \"" + dir / "experts" + "\"\n");
  std::vector<std::string> args = {"collect", "--env", "reacher", "--config", cfg, "--episodes",
                                   "1", "--max-steps", "5", "--workers", "1", "--out",
                                   dir / "a"};
  r = test::run_cli(args);
  ASSERT_EQ(r.exit_code, 0) << r.describe();
  args.back() = dir / "b";
  ASSERT_EQ(test::run_cli(args).exit_code, 0);
  const MujocoEpisode a = read_mujoco_episode(dir / "a/episode_000000.h5");
  const MujocoEpisode b = read_mujoco_episode(dir / "b/episode_000000.h5");
  EXPECT_TRUE(has(a.extra.at("expert"), "sac policy reacher.pt")) << a.extra.at("expert");
  EXPECT_EQ(a.action, b.action);

  const std::string line = one_line_error(
      test::run_cli({"collect", "--env", "hopper", "--config", cfg, "--episodes", "1",
                     "--max-steps", "2", "--workers", "1", "--out", dir / "h"}),
      "no hopper expert");
  EXPECT_TRUE(has(line, dir / "experts/hopper.pt")) << line;
  EXPECT_TRUE(one_line_error(test::run_cli({"train-expert", "--env", "walker"}), "bad env")
                  .find("unknown MuJoCo environment 'walker'") != std::string::npos);
}

}  // namespace
}  // namespace cd
