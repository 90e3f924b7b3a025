// Training dim / rip (methods/dim) on the toy set: the NLL falls and the density prefers the
// recorded future; the run folder; the same seed gives the same bytes, an interrupted member is
// retrained alone; other settings or methods are refused.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "../support/dim_toy_data.hpp"
#include "core/error.hpp"
#include "inference/dim_planner.hpp"
#include "inference/policy_runner.hpp"

namespace cd {
namespace {

using nlohmann::json;
using test::TempDir;

class DimTest : public ::testing::Test {
 protected:
  void SetUp() override { set_torch_threads(1); }
};

TEST_F(DimTest, NllDecreasesOnAToySet) {
  TempDir dir("cd-dim");
  test::write_toy_folder(dir / "data", 6);
  TrainSummary sum = test::train_toy(test::toy_settings(5, 1), "dim", dir / "data", dir / "run");
  EXPECT_EQ(sum.epochs_done, 5);
  EXPECT_TRUE(sum.has_validation);
  EXPECT_EQ(sum.val_episodes, 2);  // round(0.25 * 6)
  EXPECT_EQ(sum.train_samples, 4 * (test::kToyFrames - 20));
  DimRun run = *read_dim_run(dir / "run");
  ASSERT_EQ(run.members.size(), 1u);
  const auto& m = run.members[0].metrics;
  ASSERT_EQ(m.size(), 5u);
  EXPECT_LT(m.back().train_loss, m.front().train_loss - 1.0);
  ASSERT_TRUE(m.front().val_loss && m.back().val_loss);
  EXPECT_LT(*m.back().val_loss, *m.front().val_loss);
  EXPECT_EQ(run.members[0].best_nll, *m[run.members[0].best_epoch - 1].val_loss);
  // The learned density prefers the recorded future to a clearly wrong one.
  std::vector<DimNet> nets = test::load_members(dir / "run");
  torch::NoGradGuard no_grad;
  nets[0]->eval();
  test::ToyObservation o = test::toy_observation(dir / "data", 2, 30, run.dim);  // 4 m/s
  DimCondition c = nets[0]->condition(nets[0]->encode(o.frame), o.past);
  const double truth = nets[0]->log_prob(c, o.future).item<double>();
  const double slow = nets[0]->log_prob(c, o.future * 0.5).item<double>();
  EXPECT_GT(truth, slow + 5.0);
  // Folder contents and metrics.jsonl.
  EXPECT_EQ(test::list_dir(dir / "run"),
            (std::vector<std::string>{"causaldrive.lock", "dim.json", "member_0.pt", "metrics.jsonl"}))
      << "the run and its released lock (core/run_lock)";
  EXPECT_EQ(test::split_lines(test::read_text(dir / "run/metrics.jsonl")).size(), 5u);
}

TEST_F(DimTest, SameSeedSameBytesAndInterruptedMembersAreRetrained) {
  TempDir dir("cd-dim");
  test::write_toy_folder(dir / "data", 4);
  Settings s = test::toy_settings(2, 2);
  test::train_toy(s, "rip", dir / "data", dir / "a");
  test::train_toy(s, "rip", dir / "data", dir / "b");
  for (const char* f : {"member_0.pt", "member_1.pt"})
    EXPECT_EQ(test::read_text(dir / "a" + "/" + f), test::read_text(dir / "b" + "/" + f)) << f;
  EXPECT_NE(test::read_text(dir / "a/member_0.pt"), test::read_text(dir / "a/member_1.pt"));
  Settings other = s;
  other.train.seed = 8;
  test::train_toy(other, "rip", dir / "data", dir / "c");
  EXPECT_NE(test::read_text(dir / "a/member_0.pt"), test::read_text(dir / "c/member_0.pt"));

  // A finished folder: nothing left to train.
  TrainSummary again = test::train_toy(s, "rip", dir / "data", dir / "a");
  EXPECT_EQ(again.samples_per_s, 0.0);
  EXPECT_EQ(again.resumed_from, 4);
  // Member 1 interrupted (never marked finished): retrained alone, to the same bytes.
  json rec = json::parse(test::read_text(dir / "b/dim.json"));
  rec["members"][1]["finished"] = false;
  test::write_text(dir / "b/dim.json", rec.dump(2) + "\n");
  test::write_text(dir / "b/member_1.pt", "half-written");
  EXPECT_THROW(DimPlanner(dir / "b", "rip"), DataError);  // an unfinished run is no agent
  TrainSummary resumed = test::train_toy(s, "rip", dir / "data", dir / "b");
  EXPECT_EQ(resumed.resumed_from, 2);
  EXPECT_GT(resumed.samples_per_s, 0.0);
  for (const char* f : {"member_0.pt", "member_1.pt"})
    EXPECT_EQ(test::read_text(dir / "a" + "/" + f), test::read_text(dir / "b" + "/" + f)) << f;
  // Other settings or another method into the same folder: refused.
  Settings wider = s;
  wider.dim.hidden = 64;
  EXPECT_THROW(test::train_toy(wider, "rip", dir / "data", dir / "a"), ConfigError);
  EXPECT_THROW(test::train_toy(s, "dim", dir / "data", dir / "a"), ConfigError);
  EXPECT_EQ(test::split_lines(test::read_text(dir / "b/metrics.jsonl")).size(), 4u);
  EXPECT_THROW(DimPlanner(dir / "missing", "rip"), DataError);
}

}  // namespace
}  // namespace cd
