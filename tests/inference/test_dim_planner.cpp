// Planning with trained dim / rip runs (nn/dim_net's planner, inference/dim_planner): the
// plan raises the likelihood and follows the goal; rip's worst case is the minimum over its
// members, and the planner built from a folder uses them all.
#include "inference/dim_planner.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <vector>

#include <torch/torch.h>

#include "../support/dim_toy_data.hpp"
#include "core/error.hpp"
#include "inference/policy_runner.hpp"

namespace cd {
namespace {

using test::TempDir;

class DimPlannerTest : public ::testing::Test {
 protected:
  void SetUp() override { set_torch_threads(1); }
};

TEST_F(DimPlannerTest, PlanningRaisesTheLikelihoodAndFollowsTheGoal) {
  TempDir dir("cd-dim");
  test::write_toy_folder(dir / "data", 4);
  Settings s = test::toy_settings(3, 1);
  test::train_toy(s, "dim", dir / "data", dir / "run");
  DimEnsemble ens(test::load_members(dir / "run"));
  test::ToyObservation o = test::toy_observation(dir / "data", 1, 25, s.dim);  // 2 m/s
  DimCondition c = ens.condition(o.frame, o.past);
  const torch::Tensor mean = ens.mean_rollouts(c).select(0, 0).select(0, 0);

  // Goal weight 0 from a perturbed guess: the likelihood goes up.
  torch::manual_seed(3);
  const torch::Tensor z0 = mean + torch::randn({4, 2}) * 1.5;
  DimPlanOptions po{.iterations = 60, .lr = 0.2, .goal_weight = 0.0, .aggregation = "worst"};
  DimPlan p = plan_trajectory(ens, c, torch::zeros({2}), po, z0);
  EXPECT_GT(p.objective_after, p.objective_before + 1.0);
  ASSERT_EQ(p.log_q_before.size(), 1u);
  EXPECT_GT(p.log_q_after[0], p.log_q_before[0]);
  EXPECT_DOUBLE_EQ(p.objective_before, p.log_q_before[0]);
  EXPECT_LT((p.z - mean).norm().item<double>(), (z0 - mean).norm().item<double>());

  // A goal far ahead pulls the last waypoint forward, never lowering the objective.
  torch::Tensor goal = torch::tensor({60.0f, 0.0f});
  DimPlanOptions pg{.iterations = 30, .lr = 0.2, .goal_weight = 0.05, .aggregation = "worst"};
  DimPlan q = plan_trajectory(ens, c, goal, pg);
  EXPECT_GE(q.objective_after, q.objective_before);
  const double before = (mean[3] - goal).norm().item<double>();
  const double after = (q.z[3] - goal).norm().item<double>();
  EXPECT_LT(after, before - 0.2);
  EXPECT_GT(q.z[3][0].item<double>(), mean[3][0].item<double>());
  // Faster plan, faster implied speed; |z_1| / (5 * 0.1 s).
  EXPECT_NEAR(implied_speed(q.z, 5, 0.1), q.z[0].norm().item<double>() / 0.5, 1e-6);
  EXPECT_GE(implied_speed(q.z, 5, 0.1), implied_speed(mean, 5, 0.1));
  // The segment goal [0, goal] pulls the last waypoint towards the line from the ego to a goal
  // off to the side.
  torch::Tensor side = torch::tensor({60.0f, 30.0f});
  DimPlanOptions ps = pg;
  ps.segment_goal = true;
  ps.goal_weight = 0.5;
  DimPlan sg = plan_trajectory(ens, c, side, ps);
  const double off_before = squared_distance_to_segment(mean[3].to(torch::kFloat64), side.to(torch::kFloat64)).item<double>();
  const double off_after = squared_distance_to_segment(sg.z[3].to(torch::kFloat64), side.to(torch::kFloat64)).item<double>();
  EXPECT_LT(off_after, off_before);
  EXPECT_GE(sg.objective_after, sg.objective_before);
}

TEST(DimPlanGeometry, SegmentDistanceAndTheHorizonSpeed) {
  const torch::Tensor g = torch::tensor({10.0, 0.0}, torch::kFloat64);
  // Beside the segment: the perpendicular; before 0 or past g: the distance to that end.
  EXPECT_NEAR(squared_distance_to_segment(torch::tensor({4.0, 3.0}, torch::kFloat64), g).item<double>(), 9.0, 1e-12);
  EXPECT_NEAR(squared_distance_to_segment(torch::tensor({-3.0, 4.0}, torch::kFloat64), g).item<double>(), 25.0, 1e-12);
  EXPECT_NEAR(squared_distance_to_segment(torch::tensor({13.0, 4.0}, torch::kFloat64), g).item<double>(), 25.0, 1e-12);
  EXPECT_NEAR(squared_distance_to_segment(torch::tensor({1.0, 1.0}, torch::kFloat64),
                                          torch::zeros({2}, torch::kFloat64)).item<double>(), 2.0, 1e-12);
  // A plan (3, 4), (3, 4), (6, 8), (6, 8) over 4 x 0.5 s: first leg 5 m in 0.5 s = 10 m/s;
  // the polyline is 5 + 0 + 5 + 0 = 10 m over 2 s = 5 m/s.
  const torch::Tensor z = torch::tensor({3.0, 4.0, 3.0, 4.0, 6.0, 8.0, 6.0, 8.0}).reshape({4, 2});
  EXPECT_NEAR(implied_speed(z, 5, 0.1), 10.0, 1e-6);
  EXPECT_NEAR(implied_speed(z, 5, 0.1, true), 5.0, 1e-6);
}

TEST_F(DimPlannerTest, RipWorstCaseIsTheMinimumOfItsMembers) {
  TempDir dir("cd-dim");
  test::write_toy_folder(dir / "data", 5);
  Settings s = test::toy_settings(2, 3);
  TrainSummary sum = test::train_toy(s, "rip", dir / "data", dir / "run");
  EXPECT_EQ(sum.epochs_done, 6);  // 3 members x 2 epochs
  DimRun run = *read_dim_run(dir / "run");
  ASSERT_EQ(run.members.size(), 3u);
  // Bootstrap resamples differ between members (with this seed).
  for (const DimMember& m : run.members) {
    EXPECT_EQ(m.episodes.size(), 4u);  // as many draws as training episodes
    EXPECT_EQ(m.train_samples, 4 * (test::kToyFrames - 20));
  }
  EXPECT_FALSE(run.members[0].episodes == run.members[1].episodes &&
               run.members[1].episodes == run.members[2].episodes);
  std::vector<DimNet> nets = test::load_members(dir / "run");
  DimEnsemble ens(nets);
  test::ToyObservation o = test::toy_observation(dir / "data", 0, 10, s.dim);
  DimCondition c = ens.condition(o.frame, o.past);
  torch::NoGradGuard no_grad;
  torch::Tensor z = torch::cat({o.future, o.future * 1.3, o.future + 0.7});  // 3 trajectories
  torch::Tensor lq = ens.log_probs(c, z);  // 3 members x 3 trajectories
  ASSERT_EQ(lq.sizes(), (std::vector<int64_t>{3, 3}));
  for (int k = 0; k < 3; ++k) {
    DimCondition ck = nets[k]->condition(nets[k]->encode(o.frame), o.past);
    EXPECT_TRUE(torch::allclose(lq[k], nets[k]->log_prob(ck, z), 1e-5, 1e-3)) << k;
  }
  torch::Tensor worst = aggregate_log_q(lq, "worst");
  torch::Tensor mean = aggregate_log_q(lq, "mean");
  for (int b = 0; b < 3; ++b) {
    const double a = lq[0][b].item<double>(), bb = lq[1][b].item<double>(),
                 cc = lq[2][b].item<double>();
    EXPECT_DOUBLE_EQ(worst[b].item<double>(), std::min({a, bb, cc}));
    EXPECT_NEAR(mean[b].item<double>(), (a + bb + cc) / 3, 1e-4);
  }
  EXPECT_THROW(aggregate_log_q(lq, "best"), ConfigError);
  // The planner's objective with goal weight 0 is the worst member's log q.
  DimPlan p = plan_trajectory(ens, c, torch::zeros({2}),
                              {.iterations = 5, .lr = 0.1, .goal_weight = 0.0}, o.future[0]);
  EXPECT_DOUBLE_EQ(p.objective_before,
                   *std::min_element(p.log_q_before.begin(), p.log_q_before.end()));
  EXPECT_GE(p.objective_after, p.objective_before);
  // The planner built from the folder plans with all three.
  DimPlanner planner(dir / "run", "rip");
  EXPECT_EQ(planner.run().members.size(), 3u);
}

}  // namespace
}  // namespace cd
