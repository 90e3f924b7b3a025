// dagger through the binary on a tiny run: the closed-loop rollouts are recorded with the
// expert's labels (with beta 1 the expert drives, so they are exactly the expert's collect of
// the same episode seeds), the aggregate is every frame of the data and the rollouts, the
// record counts the labels, and a run killed after an iteration resumes to the same bytes.
// needs: sumo
#include <gtest/gtest.h>

#include <filesystem>
#include <string>

#include <nlohmann/json.hpp>

#include "../support/tiny_run.hpp"
#include "collect/collect.hpp"
#include "core/rng.hpp"
#include "data/h5_episode.hpp"
#include "datasets/episode_set.hpp"
#include "runs/checkpoint.hpp"

namespace cd {
namespace {

using nlohmann::json;

const char* kExtra =
    "\n[train]\nepochs = 1\nthreads = 1\nbatch_size = 32\nval_fraction = 0.34\n"
    "\n[model]\nfeatures = 16\nhistory = 2\nhistory_stride = 2\n"
    "\n[dagger]\niterations = 2\nepisodes = 1\nepochs = 1\nbeta = 1.0\nbeta_decay = 0.5\n"
    "seed = 11\ntraffic = \"empty\"\n";

long frames_in(const std::string& dir) {
  long n = 0;
  for (const auto& f : list_episode_files(dir)) n += static_cast<long>(read_episode(f).frames());
  return n;
}

TEST(DaggerCli, AggregatesExpertLabelledRolloutsAndResumes) {
  test::TinyRun run({.method = "dagger", .traffic = "empty", .extra = kExtra});
  const std::string a = run.run();
  const json rec = test::read_json(a + "/dagger.json");
  ASSERT_EQ(rec["iterations"].size(), 2u);
  EXPECT_DOUBLE_EQ(rec["iterations"][0]["beta"].get<double>(), 1.0);
  EXPECT_DOUBLE_EQ(rec["iterations"][1]["beta"].get<double>(), 0.5);
  const long r1 = frames_in(a + "/rollouts_01"), r2 = frames_in(a + "/rollouts_02");
  EXPECT_EQ(rec["iterations"][0]["expert_labels"].get<long>(), r1);
  EXPECT_EQ(rec["iterations"][1]["expert_labels"].get<long>(), r2);
  EXPECT_EQ(rec["expert_labels"].get<long>(), r1 + r2);

  // The last iteration trained on the expert data and both rollouts: every frame with a full
  // 2-frame history (stride 2: t >= 2) is a sample.
  const long expert = frames_in(run.data());
  const int episodes = 2 + 1 + 1;
  const Checkpoint ck = require_checkpoint(a);
  EXPECT_EQ(ck.method, "dagger");
  EXPECT_EQ(ck.train_samples + ck.val_samples, expert + r1 + r2 - 2L * episodes);
  EXPECT_EQ(ck.method_record["expert_labels"].get<long>(), r1 + r2);

  // beta 1: the expert drove iteration 1, so its rollout is the expert's own episode of that
  // seed, labels and frames alike (and the driver is named in the file).
  EpisodeMeta meta;
  const EpisodeData rolled = read_episode(a + "/rollouts_01/episode_000000.h5", &meta);
  EXPECT_NE(meta.extra.at("driver").find("dagger beta 1.0000"), std::string::npos);
  // (In-process: the derived seed is beyond the command line's range.)
  Settings es = load_settings(run.config());
  es.collect.seed = derive_seed(11, 1);
  es.collect.episodes = 1;
  es.collect.hold_s = 0;  // a rollout has a driver: the expert drives from the first step
  es.collect.out = run.dir() / "expert-same-seed";
  CollectOptions quiet;
  quiet.quiet = true;
  collect(es, quiet);
  const EpisodeData expert_run = read_episode(run.dir() / "expert-same-seed/episode_000000.h5");
  EXPECT_EQ(rolled.action, expert_run.action);
  EXPECT_EQ(rolled.speed, expert_run.speed);

  // Killed after iteration 1's commit, then resumed: the same bytes as the run that never
  // stopped.
  const std::string b = run.dir() / "killed";
  {
    test::ScopedEnv crash("CAUSALDRIVE_INJECT_CRASH", "dagger:1");
    test::CommandResult r = test::run_cli(test::train_args(run.config(), "dagger", run.data(), b));
    EXPECT_FALSE(r.exited && r.exit_code == 0) << r.describe();
  }
  EXPECT_EQ(test::read_json(b + "/dagger.json")["iterations"].size(), 1u);
  EXPECT_FALSE(std::filesystem::exists(b + "/" + kCheckpointJson));
  test::run_cli_ok(test::train_args(run.config(), "dagger", run.data(), b));
  EXPECT_EQ(test::read_text(a + "/" + kBestFile), test::read_text(b + "/" + kBestFile));
  EXPECT_EQ(test::read_text(a + "/dagger.json"), test::read_text(b + "/dagger.json"));
}

}  // namespace
}  // namespace cd
