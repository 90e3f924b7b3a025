// dim / rip through the binary on the toy set: a rerun trains nothing, dim trains one model,
// and wrong run folders (another method's, a missing one, another frame size) give one-line
// errors in train and eval. (A tiny dim run in the simulator is in test_learned_agents.cpp.)
#include <gtest/gtest.h>

#include <string>

#include <nlohmann/json.hpp>

#include "../support/dim_toy_data.hpp"
#include "../support/tiny_run.hpp"
#include "runs/dim_run.hpp"

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

TEST(DimCli, ViewLimitsTheChannelsTheModelSees) {
  // Two folders that differ only in channel 5 (ch5): a dim that sees ch2+ch3 trains to the
  // same bytes on both; one that sees every channel does not.
  TempDir dir("cd-dim");
  test::write_toy_folder(dir / "a", 3);
  test::write_toy_folder(dir / "b", 3);
  for (int e = 0; e < 3; ++e) {
    const std::string file = dir / ("b/" + test::fake_episode_name(e));
    EpisodeMeta meta;
    EpisodeData d = read_episode(file, &meta);
    const size_t pixels = static_cast<size_t>(d.height) * d.width;
    for (size_t t = 0; t < d.frames(); ++t)
      for (size_t i = 0; i < pixels; i += 3) d.bev[t * d.frame_bytes() + 5 * pixels + i] ^= 255;
    write_episode(file, meta, d);
  }
  auto train = [&](const std::string& view, const std::string& data, const std::string& out) {
    const std::string cfg = dir / ("c" + view + ".toml");
    test::write_text(cfg, "[train]\nepochs = 1\nthreads = 1\nbatch_size = 16\n"
                          "[dim]\nfeatures = 16\nhidden = 16\nview = \"" + view + "\"\n");
    return test::run_cli(test::train_args(cfg, "dim", dir / data, dir / out));
  };
  ASSERT_EQ(train("ch2+ch3", "a", "va").exit_code, 0);
  ASSERT_EQ(train("ch2+ch3", "b", "vb").exit_code, 0);
  EXPECT_EQ(test::read_text(dir / ("va/" + dim_member_file(0))), test::read_text(dir / ("vb/" + dim_member_file(0))));
  ASSERT_EQ(train("", "a", "fa").exit_code, 0);
  ASSERT_EQ(train("", "b", "fb").exit_code, 0);
  EXPECT_NE(test::read_text(dir / ("fa/" + dim_member_file(0))), test::read_text(dir / ("fb/" + dim_member_file(0))));
  expect_one_line_error(train("lights", "a", "bad"), "dim.view: no BEV channel 'lights'");
}

TEST(DimCli, WrongFoldersGiveOneLineErrors) {
  CD_NEEDS_SUMO();
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
