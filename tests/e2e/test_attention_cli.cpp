// `causaldrive attention` through the real binary: the grids and attention.json of a tiny
// bc-so run, --json, and one line for each user error (missing checkpoint, a run that is not
// an image policy, data of another frame format, N < 1, an unknown selection).
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "../support/fake_episodes.hpp"
#include "../support/tiny_run.hpp"

namespace cd {
namespace {

using nlohmann::json;
using test::CommandResult;
using test::expect_one_line_error;
using test::TempDir;

TEST(AttentionCli, WritesMapsAndRefusesWhatItCannotExplain) {
  TempDir dir("cd-attention-cli");
  const std::string config = dir / "learn.toml";
  test::write_text(config, test::learn_config_toml(1));
  const std::string data = dir / "data", small = dir / "small";
  test::write_fake_folder(data, 2, {.frames = 16});
  test::write_fake_folder(small, 2, {.frames = 16, .height = 16, .width = 16});
  const std::string run = dir / "so";
  test::run_cli_ok(test::train_args(config, "bc-so", data, run));

  const std::string out = dir / "maps";
  CommandResult r = test::run_cli_ok(
      {"attention", "--checkpoint", run, "--data", data, "--out", out, "--frames", "2",
       "--select", "all", "--json"});
  json j = json::parse(r.out);
  EXPECT_EQ(j["method"], "bc-so");
  EXPECT_EQ(j["frames"].size(), 2u);
  EXPECT_EQ(j, test::read_json(out + "/attention.json"));
  EXPECT_EQ(test::list_dir(out), (std::vector<std::string>{"attention.json", "attention_000.png",
                                                           "attention_001.png"}));
  CommandResult table = test::run_cli_ok(
      {"attention", "--checkpoint", run, "--data", data, "--out", out, "--frames", "1"});
  EXPECT_NE(table.out.find("attention"), std::string::npos) << table.out;
  EXPECT_NE(table.out.find("none"), std::string::npos) << table.out;

  auto attention = [&](const std::string& checkpoint, const std::string& d,
                       const std::vector<std::string>& more = {}) {
    std::vector<std::string> a = {"attention", "--checkpoint", checkpoint, "--data", d,
                                  "--out", dir / "err"};
    a.insert(a.end(), more.begin(), more.end());
    return test::run_cli(a);
  };
  expect_one_line_error(attention(dir / "nothing", data), "not found");
  // A run of a method without an image policy (its record is all that is read).
  test::fs::create_directories(dir / "dim");
  test::write_text(dir / "dim/dim.json", R"({"method": "dim"})");
  expect_one_line_error(attention(dir / "dim", data),
                        "need an image policy (bc-so, bc-oh, residual, fca, keyframe, hd, dagger)");
  expect_one_line_error(attention(run, small), "16x16");
  expect_one_line_error(attention(run, data, {"--frames", "0"}), "--frames must be at least 1");
  expect_one_line_error(attention(run, data, {"--select", "red"}), "unknown --select 'red'");
  expect_one_line_error(attention(run, data, {"--select", "light"}), "no causes/tl_state");
  EXPECT_FALSE(test::fs::exists(dir / "err/attention.json"));
}

}  // namespace
}  // namespace cd
