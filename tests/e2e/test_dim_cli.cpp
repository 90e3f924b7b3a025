// dim / rip through the binary on the toy set: a rerun trains nothing, dim trains one model,
// and wrong run folders (another method's, a missing one, another frame size) give one-line
// errors in train and eval. (A tiny dim run in the simulator is in test_learned_agents.cpp.)
#include <gtest/gtest.h>

#include <string>

#include <nlohmann/json.hpp>

#include "../support/dim_toy_data.hpp"
#include "../support/tiny_run.hpp"

namespace cd {
namespace {

using nlohmann::json;
using test::expect_one_line_error;
using test::TempDir;

TEST(DimCli, SamplesWhoseFutureHoldsNoiseAreLeftOut) {
  TempDir dir("cd-dim");
  // 60 frames, future reach 4 waypoints x 5 steps = 20: t = 0..39 per episode. Noise at steps
  // 30..34 touches the future of t = 11..34: 16 samples per episode remain.
  test::write_toy_folder(dir / "data", 3, {30, 35});
  const std::string cfg = dir / "c.toml";
  test::write_text(cfg, "[train]\nepochs = 1\nthreads = 1\nbatch_size = 16\n"
                        "[dim]\nfeatures = 16\nhidden = 16\n");
  auto t = test::run_cli(test::train_args(cfg, "dim", dir / "data", dir / "dim"));
  ASSERT_EQ(t.exit_code, 0) << t.describe();
  const json samples = json::parse(test::read_text(dir / "dim/dim.json"))["samples"];
  EXPECT_EQ(samples["train"].get<long>() + samples["val"].get<long>(), 3 * 16) << samples.dump();
}

TEST(DimCli, WrongFoldersGiveOneLineErrors) {
  TempDir dir("cd-dim");
  test::write_toy_folder(dir / "data", 3);
  const std::string cfg = dir / "c.toml";
  test::write_text(cfg, "[train]\nepochs = 1\nthreads = 1\nbatch_size = 16\n"
                        "[dim]\nfeatures = 16\nhidden = 16\nensemble = 2\n");
  auto t = test::run_cli(test::train_args(cfg, "dim", dir / "data", dir / "dim"));
  ASSERT_EQ(t.exit_code, 0) << t.describe();
  EXPECT_NE(t.out.find("trained dim"), std::string::npos) << t.out;
  auto again = test::run_cli(test::train_args(cfg, "dim", dir / "data", dir / "dim"));
  ASSERT_EQ(again.exit_code, 0) << again.describe();
  EXPECT_NE(again.out.find("nothing left to train"), std::string::npos) << again.out;
  // dim trains one model whatever dim.ensemble says.
  EXPECT_EQ(json::parse(test::read_text(dir / "dim/dim.json"))["members"].size(), 1u);

  expect_one_line_error(test::run_cli(test::train_args(cfg, "rip", dir / "data", dir / "dim")),
                        "method 'dim'");
  test::fs::create_directories(dir / "bc");
  test::write_text(dir / "bc/checkpoint.json", R"({"method": "bc-oh"})");
  expect_one_line_error(test::run_cli(test::train_args(cfg, "dim", dir / "data", dir / "bc")),
                        "method 'bc-oh'");
  expect_one_line_error(test::run_cli({"eval", "--config", cfg, "--agent", "rip", "--checkpoint",
                                       dir / "dim", "--suite", "quickstart", "--out", dir / "e1"}),
                        "method 'dim'");
  expect_one_line_error(test::run_cli({"eval", "--config", cfg, "--agent", "dim", "--checkpoint",
                                       dir / "bc", "--suite", "quickstart", "--out", dir / "e2"}),
                        "bc-oh");
  expect_one_line_error(test::run_cli({"eval", "--config", cfg, "--agent", "dim", "--checkpoint",
                                       dir / "nowhere", "--suite", "quickstart", "--out",
                                       dir / "e3"}),
                        "nowhere");
  // Trained on 32x32 frames, evaluated on the default 64x64 BEV.
  expect_one_line_error(test::run_cli({"eval", "--config", cfg, "--agent", "dim", "--checkpoint",
                                       dir / "dim", "--suite", "quickstart", "--out", dir / "e4",
                                       "--workers", "1"}),
                        "32x32");
}

}  // namespace
}  // namespace cd
