// `causaldrive train` and `causaldrive probe` through the real binary: output files, resume
// after kill -9 with identical bytes, error paths, the probe's JSON.
#include <gtest/gtest.h>
#include <signal.h>

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
using test::read_jsonl;
using test::TempDir;
using test::train_args;

struct Fixture {
  TempDir dir{"cd-learn-cli"};
  std::string config, data;
  explicit Fixture(int episodes = 3, int frames = 40, int epochs = 2) {
    config = dir / "learn.toml";
    test::write_text(config, test::learn_config_toml(epochs));
    data = dir / "data";
    test::write_fake_folder(data, episodes, {.frames = frames});
  }
};

TEST(TrainCli, WritesTheCheckpointFolder) {
  Fixture f;
  const std::string out = f.dir / "ck";
  CommandResult r = test::run_cli(train_args(f.config, "bc-oh", f.data, out));
  ASSERT_TRUE(r.exited && r.exit_code == 0) << r.describe();
  EXPECT_NE(r.out.find("trained bc-oh"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("best epoch"), std::string::npos) << r.out;
  EXPECT_EQ(test::list_dir(out), (std::vector<std::string>{"best.pt", "causaldrive.lock", "checkpoint.json",
                                                           "metrics.jsonl", "model.pt",
                                                           "optimizer.pt"}));
  json ck = json::parse(test::read_text(out + "/checkpoint.json"));
  EXPECT_EQ(ck["method"], "bc-oh");
  EXPECT_EQ(ck["epochs_done"], 2);
  EXPECT_EQ(ck["settings"]["model"]["history"], 3);
  EXPECT_EQ(ck["settings"]["model"]["features"], 32);
  EXPECT_EQ(ck["input"]["history"], 3);
  EXPECT_EQ(ck["input"]["channels"], 8);
  EXPECT_EQ(ck["episodes"]["val"], 1);
  EXPECT_EQ(ck["samples"]["train"], 2 * (40 - 4));
  EXPECT_EQ(ck["samples"]["val"], 40 - 4);
  EXPECT_GE(ck["best_epoch"].get<int>(), 1);
  ASSERT_EQ(ck["metrics"].size(), 2u);
  auto lines = read_jsonl(out + "/metrics.jsonl");
  ASSERT_EQ(lines.size(), 2u);
  for (int i = 0; i < 2; ++i) {
    EXPECT_EQ(lines[i]["epoch"], i + 1);
    for (const char* key : {"train_loss", "val_loss", "lr", "seconds", "samples_per_s"})
      EXPECT_TRUE(lines[i][key].is_number()) << key << " in " << lines[i].dump();
    EXPECT_EQ(lines[i], ck["metrics"][i]);
  }

  // Rerunning the finished command trains nothing and changes no weights.
  const std::string model = test::read_text(out + "/model.pt");
  CommandResult again = test::run_cli(train_args(f.config, "bc-oh", f.data, out));
  ASSERT_TRUE(again.exited && again.exit_code == 0) << again.describe();
  EXPECT_NE(again.out.find("nothing left to train"), std::string::npos) << again.out;
  EXPECT_EQ(test::read_text(out + "/model.pt"), model);
  EXPECT_EQ(read_jsonl(out + "/metrics.jsonl").size(), 2u);

  // More epochs continue the same folder.
  CommandResult more = test::run_cli(train_args(f.config, "bc-oh", f.data, out, {"--epochs", "3"}));
  ASSERT_TRUE(more.exited && more.exit_code == 0) << more.describe();
  EXPECT_EQ(read_jsonl(out + "/metrics.jsonl").size(), 3u);
}

// Reads epochs_done from checkpoint.json, -1 while there is none.
int epochs_done(const std::string& dir) {
  std::error_code ec;
  if (!test::fs::exists(dir + "/checkpoint.json", ec)) return -1;
  try {
    return json::parse(test::read_text(dir + "/checkpoint.json"))["epochs_done"].get<int>();
  } catch (const std::exception&) {
    return -1;
  }
}

TEST(TrainCli, KillNineMidRunThenResumeGivesTheSameBytes) {
  Fixture f(4, 60, 3);
  const std::string straight = f.dir / "straight", killed = f.dir / "killed";
  CommandResult r = test::run_cli(train_args(f.config, "bc-oh", f.data, straight));
  ASSERT_TRUE(r.exited && r.exit_code == 0) << r.describe();

  // kill -9 right after epoch 1 of 3 is committed (the hook of core/fault.hpp).
  {
    test::ScopedEnv crash("CAUSALDRIVE_INJECT_CRASH", "train:1");
    CommandResult k = test::run_cli(train_args(f.config, "bc-oh", f.data, killed));
    ASSERT_TRUE(!k.exited && k.signal == SIGKILL) << k.describe();
  }
  EXPECT_EQ(epochs_done(killed), 1);

  CommandResult resumed = test::run_cli(train_args(f.config, "bc-oh", f.data, killed));
  ASSERT_TRUE(resumed.exited && resumed.exit_code == 0) << resumed.describe();
  EXPECT_NE(resumed.err.find("resuming"), std::string::npos) << resumed.err;

  auto lines = read_jsonl(killed + "/metrics.jsonl");
  ASSERT_EQ(lines.size(), 3u);
  for (int i = 0; i < 3; ++i) EXPECT_EQ(lines[i]["epoch"], i + 1);
  auto ref = read_jsonl(straight + "/metrics.jsonl");
  for (int i = 0; i < 3; ++i) {
    EXPECT_EQ(lines[i]["train_loss"], ref[i]["train_loss"]) << "epoch " << i + 1;
    EXPECT_EQ(lines[i]["val_loss"], ref[i]["val_loss"]) << "epoch " << i + 1;
  }
  EXPECT_TRUE(test::read_text(killed + "/model.pt") == test::read_text(straight + "/model.pt"))
      << "model.pt of the resumed run differs from the uninterrupted run's";
  EXPECT_TRUE(test::read_text(killed + "/best.pt") == test::read_text(straight + "/best.pt"));
  for (const auto& name : test::list_dir(killed))
    EXPECT_FALSE(test::ends_with(name, ".pending") || test::ends_with(name, ".tmp")) << name;
}

TEST(TrainCli, ErrorsAreOneLine) {
  Fixture f(2, 20);
  expect_one_line_error(test::run_cli(train_args(f.config, "bc-oh", f.dir / "nope", f.dir / "o1")),
                        "not found");
  expect_one_line_error(test::run_cli(train_args(f.config, "bc-xx", f.data, f.dir / "o2")),
                        "unknown method 'bc-xx'");
  expect_one_line_error(test::run_cli(train_args(f.config, "expert", f.data, f.dir / "o3")),
                        "method 'expert' is an agent without training (trainable: bc-so, bc-oh, "
                        "residual, fca, keyframe, hd, dagger, dim, rip, cim, cim-mlp, "
                        "cim-entangled)");
  // Seed 001's keys are checked like every other: the file and the key, in one line.
  const std::pair<const char*, const char*> bad_keys[] = {
      {"[residual]\nmemory_target = \"bogus\"\n", "memory_target"},
      {"[residual]\nbranches = 0\n", "branches"},
      {"[residual]\npolicy = \"both\"\n", "policy"},
      {"[fca]\nadversary_weight = -1\n", "adversary_weight"},
      {"[keyframe]\nmode = \"max\"\n", "mode"},
      {"[hd]\np = 1.5\n", "p"},
      {"[dagger]\niterations = 0\n", "iterations"},
      {"[dagger]\nbogus = 1\n", "bogus"}};
  int k = 0;
  for (const auto& [text, key] : bad_keys) {
    const std::string cfg = f.dir / ("bad" + std::to_string(k++) + ".toml");
    test::write_text(cfg, test::read_text(f.config) + "\n" + text);
    expect_one_line_error(test::run_cli(train_args(cfg, "residual", f.data, f.dir / "o5")), key);
  }
  // Settings the method cannot have.
  const std::string so = f.dir / "history1.toml";
  test::write_text(so, test::read_text(f.config) + "\n[residual]\nbranches = 2\n"
                                                    "memory_target = \"action\"\n");
  expect_one_line_error(test::run_cli(train_args(so, "residual", f.data, f.dir / "o6")),
                        "residual.branches > 1 needs residual.memory_target");
  test::write_fake_folder(f.dir / "empty", 0);
  expect_one_line_error(test::run_cli(train_args(f.config, "bc-oh", f.dir / "empty", f.dir / "o4")),
                        "no episode_");

  // A folder holding another method's checkpoint, or one trained with other settings.
  const std::string out = f.dir / "so";
  CommandResult r = test::run_cli(train_args(f.config, "bc-so", f.data, out, {"--epochs", "1"}));
  ASSERT_TRUE(r.exited && r.exit_code == 0) << r.describe();
  expect_one_line_error(test::run_cli(train_args(f.config, "bc-oh", f.data, out)),
                        "method 'bc-so', not 'bc-oh'");
  expect_one_line_error(test::run_cli(train_args(f.config, "bc-so", f.data, out, {"--seed", "5"})),
                        "train.seed 0 -> 5");
}

TEST(ProbeCli, ReportsTheHistoryEffect) {
  Fixture f(3, 40, 1);
  const std::string oh = f.dir / "oh", so = f.dir / "so";
  CommandResult r = test::run_cli(train_args(f.config, "bc-oh", f.data, oh));
  ASSERT_TRUE(r.exited && r.exit_code == 0) << r.describe();
  CommandResult p = test::run_cli({"probe", "--checkpoint", oh, "--data", f.data, "--json"});
  ASSERT_TRUE(p.exited && p.exit_code == 0) << p.describe();
  json j = json::parse(p.out);
  for (const char* key : {"method", "history", "history_stride", "output", "moving_speed",
                          "frames", "stopped_frames", "probed_frames", "path_free", "blocked"})
    EXPECT_TRUE(j.contains(key)) << key;
  EXPECT_EQ(j["method"], "bc-oh");
  EXPECT_EQ(j["history"], 3);
  EXPECT_EQ(j["output"], "throttle_minus_brake");
  EXPECT_EQ(j["frames"], 3 * 40);
  // Stopped (speed < 0.5): t % 20 in {0, 1}, with t >= 4: t = 20, 21 in each episode.
  EXPECT_EQ(j["stopped_frames"], 3 * 2);
  EXPECT_EQ(j["path_free"]["count"], 3);  // t = 20 (even)
  EXPECT_EQ(j["blocked"]["count"], 3);    // t = 21
  for (const char* group : {"path_free", "blocked"})
    for (const char* key : {"mean_real", "mean_moving", "mean_static", "history_effect",
                            "moving_minus_static"})
      EXPECT_TRUE(j[group][key].is_number()) << group << "." << key;
  EXPECT_GE(j["path_free"]["history_effect"].get<double>(), 0.0);

  CommandResult limited =
      test::run_cli({"probe", "--checkpoint", oh, "--data", f.data, "--max-frames", "2", "--json"});
  ASSERT_TRUE(limited.exited && limited.exit_code == 0) << limited.describe();
  EXPECT_EQ(json::parse(limited.out)["probed_frames"], 2);

  CommandResult table = test::run_cli({"probe", "--checkpoint", oh, "--data", f.data});
  ASSERT_TRUE(table.exited && table.exit_code == 0) << table.describe();
  EXPECT_NE(table.out.find("|moving-static|"), std::string::npos) << table.out;

  ASSERT_EQ(test::run_cli(train_args(f.config, "bc-so", f.data, so)).exit_code, 0);
  expect_one_line_error(test::run_cli({"probe", "--checkpoint", so, "--data", f.data}),
                        "needs a history policy such as bc-oh");
}

}  // namespace
}  // namespace cd

namespace cd {
namespace {

TEST(DiagnoseCli, ComparesThePolicyWithTheLabelsSituationBySituation) {
  test::TempDir dir{"cd-diagnose-cli"};
  const std::string config = dir / "learn.toml", data = dir / "data", plain = dir / "plain";
  test::write_text(config, test::learn_config_toml(1));
  test::write_fake_folder(data, 3, {.frames = 40, .situation_causes = true});
  test::write_fake_folder(plain, 3, {.frames = 40});
  const std::string oh = dir / "oh";
  ASSERT_EQ(test::run_cli(train_args(config, "bc-oh", data, oh)).exit_code, 0);

  const std::string plots = dir / "plots";
  CommandResult r = test::run_cli(
      {"diagnose", "--checkpoint", oh, "--data", data, "--json", "--plots", plots});
  ASSERT_TRUE(r.exited && r.exit_code == 0) << r.describe();
  json j = json::parse(r.out);
  EXPECT_EQ(j["method"], "bc-oh");
  EXPECT_EQ(j["split"], "val");
  // One validation episode of 40 frames; history 3, stride 2: t = 4 .. 39.
  EXPECT_EQ(j["frames"], 36);
  EXPECT_EQ(j["components"], json({"throttle", "brake"}));
  const json& all = j["situations"]["all"];
  EXPECT_EQ(all["count"], 36);
  // The throttle label is t / 1000: mean (4 + 39) / 2000.
  EXPECT_NEAR(all["throttle"]["label_mean"].get<double>(), 0.0215, 1e-6);
  // Standing (speed 0.25 (t % 20) < 0.5): t = 20, 21, both 5 m before a red light (t % 20 < 5).
  EXPECT_EQ(j["situations"]["standing_blocked"]["count"], 2);
  EXPECT_EQ(j["situations"]["standing_free"]["count"], 0);
  for (const char* s : {"starting", "cruising", "slowing_red", "following"})
    EXPECT_TRUE(j["situations"].contains(s)) << s;
  const auto pngs = test::list_dir(plots);
  ASSERT_EQ(pngs.size(), 1u);  // the one validation episode
  EXPECT_TRUE(test::ends_with(pngs[0], ".png"));

  // The run records its validation files, and the diagnosis compares those: a folder that grew
  // (a fourth episode, the same count held out) gives the same episodes, not a new draw.
  const json record = test::read_json(oh + "/checkpoint.json");
  ASSERT_EQ(record["episodes"]["val_files"].size(), 1u) << record["episodes"].dump();
  EXPECT_EQ(j["episodes"], record["episodes"]["val_files"]);
  const std::string grown = dir / "grown", grown_run = dir / "grown-oh";
  test::write_fake_folder(grown, 3, {.frames = 40, .situation_causes = true});
  ASSERT_EQ(test::run_cli(train_args(config, "bc-oh", grown, grown_run)).exit_code, 0);
  const json before = json::parse(test::run_cli({"diagnose", "--checkpoint", grown_run, "--data",
                                                 grown, "--json"}).out);
  test::fs::copy_file(grown + "/episode_000000.h5", grown + "/episode_000003.h5");
  CommandResult after =
      test::run_cli({"diagnose", "--checkpoint", grown_run, "--data", grown, "--json"});
  ASSERT_EQ(after.exit_code, 0) << after.describe();
  EXPECT_EQ(json::parse(after.out)["episodes"], before["episodes"]);
  EXPECT_EQ(json::parse(after.out)["frames"], before["frames"]);
  // A validation file that is gone is one line.
  test::fs::remove(grown + "/" + before["episodes"][0].get<std::string>());
  expect_one_line_error(
      test::run_cli({"diagnose", "--checkpoint", grown_run, "--data", grown, "--json"}),
      "no longer holds " + before["episodes"][0].get<std::string>());

  CommandResult every =
      test::run_cli({"diagnose", "--checkpoint", oh, "--data", data, "--split", "all", "--json"});
  ASSERT_EQ(every.exit_code, 0) << every.describe();
  EXPECT_EQ(json::parse(every.out)["frames"], 3 * 36);
  CommandResult table = test::run_cli({"diagnose", "--checkpoint", oh, "--data", data});
  ASSERT_EQ(table.exit_code, 0) << table.describe();
  EXPECT_NE(table.out.find("standing_blocked"), std::string::npos) << table.out;

  expect_one_line_error(
      test::run_cli({"diagnose", "--checkpoint", oh, "--data", plain, "--split", "val"}),
      "is not the data folder");
  expect_one_line_error(
      test::run_cli({"diagnose", "--checkpoint", oh, "--data", plain, "--split", "all"}),
      "has no causes/");
  expect_one_line_error(test::run_cli({"diagnose", "--checkpoint", oh, "--data", data, "--plots",
                                       plots, "--plot-episodes", "7"}),
                        "episode 7 is not in");
  expect_one_line_error(test::run_cli({"diagnose", "--checkpoint", dir / "none", "--data", data}),
                        "none");
}

}  // namespace
}  // namespace cd
