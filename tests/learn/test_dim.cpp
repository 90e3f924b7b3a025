// dim / rip: the trajectory density, maximum-likelihood training, the planner, the ensemble's
// aggregation, determinism, the run folder, and the agent end to end through the CLI.
#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/error.hpp"
#include "datasets/trajectory.hpp"
#include "inference/dim_planner.hpp"
#include "runs/dim_run.hpp"
#include "methods/method.hpp"
#include "datasets/episode_set.hpp"
#include "inference/policy_runner.hpp"
#include "learn_data.hpp"
#include "nn/dim_net.hpp"

namespace cd {
namespace {

using nlohmann::json;
using test::TempDir;

constexpr int kToyFrames = 60;

// Straight-line episodes: episode e drives at speed 2 * (e % 3) m/s with heading 0.4 e, and
// its frames show a box whose row tells that speed class (channels 2..7).
void write_toy_folder(const std::string& dir, int episodes) {
  test::FakeEpisodeSpec spec{.frames = kToyFrames, .channels = 8, .height = 32, .width = 32};
  test::fs::create_directories(dir);
  for (int e = 0; e < episodes; ++e) {
    EpisodeData d = test::fake_episode(e, spec);
    const size_t pixels = 32 * 32, fb = 8 * pixels;
    const double v = 2.0 * (e % 3), h = 0.4 * e;
    d.pose.clear();
    for (int t = 0; t < kToyFrames; ++t) {
      uint8_t* f = d.bev.data() + t * fb;
      std::fill(f + 2 * pixels, f + fb, uint8_t{0});
      const int row = 4 + 10 * (e % 3);
      for (int c = 2; c < 8; ++c)
        for (int y = row; y < row + 6; ++y)
          for (int x = 8; x < 24; ++x) f[c * pixels + y * 32 + x] = 255;
      const double s = v * 0.1 * t;
      d.pose.insert(d.pose.end(), {static_cast<float>(5.0 * e + std::cos(h) * s),
                                   static_cast<float>(-3.0 * e + std::sin(h) * s),
                                   static_cast<float>(h)});
      d.speed[t] = static_cast<float>(v);
    }
    write_episode(dir + "/" + test::fake_episode_name(e), test::fake_meta(spec), d);
  }
}

Settings toy_settings(int epochs = 4, int ensemble = 3) {
  Settings s;
  s.train.epochs = epochs;
  s.train.batch_size = 16;
  s.train.lr = 3e-3;
  s.train.threads = 1;
  s.train.val_fraction = 0.25;
  s.train.seed = 7;
  s.dim.features = 16;
  s.dim.hidden = 32;
  s.dim.ensemble = ensemble;
  return s;
}

TrainSummary train(const Settings& s, const std::string& method, const std::string& data,
                   const std::string& out) {
  TrainRequest r;
  r.method = method;
  r.data_dir = data;
  r.out_dir = out;
  r.quiet = true;
  return train_method(s, r);
}

// The members of a finished run folder, as the planner builds them.
std::vector<DimNet> load_members(const std::string& dir) {
  DimRun run = *read_dim_run(dir);
  DimNetOptions o;
  o.channels = run.input.channels;
  o.height = run.input.height;
  o.width = run.input.width;
  o.horizon = run.dim.horizon;
  o.past = run.dim.past;
  o.features = run.dim.features;
  o.hidden = run.dim.hidden;
  o.min_std = run.dim.min_std;
  std::vector<DimNet> nets;
  for (int k = 0; k < static_cast<int>(run.members.size()); ++k) {
    DimNet net(o);
    const std::string p = dir + "/" + dim_member_file(k);
    load_module_bytes(*net, test::read_text(p), torch::kCPU, p);
    nets.push_back(net);
  }
  return nets;
}

// Frame t of episode e of a folder as a 1 x C x H x W tensor, and its past positions.
struct ToyObservation {
  torch::Tensor frame, past, future;
};
ToyObservation toy_observation(const std::string& data, int e, int t, const DimSettings& d) {
  EpisodeSet set = load_episode_set(data);
  ToyObservation o;
  o.frame = torch::empty({1, set.channels, set.height, set.width});
  set.planes01(e, t, o.frame.data_ptr<float>());
  o.past = torch::empty({1, d.past, 2});
  o.future = torch::empty({1, d.horizon, 2});
  dim_sample_positions(set.episodes[e], t, d, o.past.data_ptr<float>(),
                       o.future.data_ptr<float>());
  return o;
}

class DimTest : public ::testing::Test {
 protected:
  void SetUp() override { set_torch_threads(1); }
};

TEST(DimSamples, PositionsAreInTheEgoFrameAndClampedAtTheStart) {
  TempDir dir("cd-dim");
  write_toy_folder(dir / "data", 3);
  EpisodeSet set = load_episode_set(dir / "data");
  DimSettings d;  // horizon 4, step 5, past 4
  float past[8], future[8];
  dim_sample_positions(set.episodes[2], 7, d, past, future);  // 4 m/s, heading 0.8
  for (int k = 0; k < 4; ++k) {
    EXPECT_NEAR(future[2 * k], 4.0 * 0.5 * (k + 1), 1e-4);  // straight ahead
    EXPECT_NEAR(future[2 * k + 1], 0.0, 1e-4);
  }
  EXPECT_NEAR(past[0], -2.0, 1e-4);  // t = 2
  EXPECT_NEAR(past[2], -2.8, 1e-4);  // t = -3 -> 0
  EXPECT_NEAR(past[6], -2.8, 1e-4);
  EXPECT_NEAR(past[7], 0.0, 1e-4);
}

TEST_F(DimTest, DensityIsAutoregressiveAndTheEnsembleMatchesItsMembers) {
  torch::manual_seed(1);
  DimNetOptions o{.channels = 8, .height = 32, .width = 32, .horizon = 4, .past = 4,
                  .features = 16, .hidden = 32};
  DimNet net(o);
  net->eval();
  torch::NoGradGuard no_grad;
  torch::Tensor frame = (torch::rand({2, 8, 32, 32}) > 0.5).to(torch::kFloat32);
  torch::Tensor past = torch::randn({2, 4, 2});
  torch::Tensor z = torch::randn({2, 4, 2}) * 3;
  DimCondition c = net->condition(net->encode(frame), past);
  DimGaussians g = net->gaussians(c, z);
  // Changing z_3 leaves the Gaussians of steps 1..3 as they were and changes step 4's.
  torch::Tensor z2 = z.clone();
  z2.index_put_({torch::indexing::Slice(), 2}, z2.index({torch::indexing::Slice(), 2}) + 1.5);
  DimGaussians g2 = net->gaussians(c, z2);
  EXPECT_TRUE(torch::allclose(g.mean.narrow(2, 0, 3), g2.mean.narrow(2, 0, 3)));
  EXPECT_TRUE(torch::allclose(g.std.narrow(2, 0, 3), g2.std.narrow(2, 0, 3)));
  EXPECT_FALSE(torch::allclose(g.mean.narrow(2, 3, 1), g2.mean.narrow(2, 3, 1)));
  EXPECT_GE(g.std.min().item<double>(), o.min_std);
  // log q equals the sum of per-coordinate normal log densities.
  torch::Tensor u = (z.unsqueeze(0) - g.mean) / g.std;
  torch::Tensor manual = (-0.5 * u.square() - g.std.log() - 0.5 * std::log(2 * M_PI)).sum({2, 3});
  EXPECT_TRUE(torch::allclose(net->log_prob(c, z), manual.squeeze(0), 1e-5, 1e-4));
  // The mean rollout is the fixed point of its own means.
  torch::Tensor m = net->mean_rollout(c);
  EXPECT_TRUE(torch::allclose(net->gaussians(c, m).mean.squeeze(0), m, 1e-5, 1e-5));
  // A one-member ensemble gives the net's own log q.
  DimEnsemble ens({net});
  DimCondition ce = ens.condition(frame.narrow(0, 0, 1), past.narrow(0, 0, 1));
  EXPECT_TRUE(torch::allclose(ens.log_probs(ce, z.narrow(0, 0, 1)).squeeze(0),
                              net->log_prob(c, z).narrow(0, 0, 1), 1e-5, 1e-4));
}

TEST_F(DimTest, NllDecreasesOnAToySet) {
  TempDir dir("cd-dim");
  write_toy_folder(dir / "data", 6);
  TrainSummary sum = train(toy_settings(5, 1), "dim", dir / "data", dir / "run");
  EXPECT_EQ(sum.epochs_done, 5);
  EXPECT_TRUE(sum.has_validation);
  EXPECT_EQ(sum.val_episodes, 2);  // round(0.25 * 6)
  EXPECT_EQ(sum.train_samples, 4 * (kToyFrames - 20));
  DimRun run = *read_dim_run(dir / "run");
  ASSERT_EQ(run.members.size(), 1u);
  const auto& m = run.members[0].metrics;
  ASSERT_EQ(m.size(), 5u);
  EXPECT_LT(m.back().train_loss, m.front().train_loss - 1.0);
  ASSERT_TRUE(m.front().val_loss && m.back().val_loss);
  EXPECT_LT(*m.back().val_loss, *m.front().val_loss);
  EXPECT_EQ(run.members[0].best_nll, *m[run.members[0].best_epoch - 1].val_loss);
  // The learned density prefers the recorded future to a clearly wrong one.
  std::vector<DimNet> nets = load_members(dir / "run");
  torch::NoGradGuard no_grad;
  nets[0]->eval();
  ToyObservation o = toy_observation(dir / "data", 2, 30, run.dim);  // 4 m/s
  DimCondition c = nets[0]->condition(nets[0]->encode(o.frame), o.past);
  const double truth = nets[0]->log_prob(c, o.future).item<double>();
  const double slow = nets[0]->log_prob(c, o.future * 0.5).item<double>();
  EXPECT_GT(truth, slow + 5.0);
  // Folder contents and metrics.jsonl.
  EXPECT_EQ(test::list_dir(dir / "run"),
            (std::vector<std::string>{"dim.json", "member_0.pt", "metrics.jsonl"}));
  EXPECT_EQ(test::split_lines(test::read_text(dir / "run/metrics.jsonl")).size(), 5u);
}

TEST_F(DimTest, PlanningRaisesTheLikelihoodAndFollowsTheGoal) {
  TempDir dir("cd-dim");
  write_toy_folder(dir / "data", 4);
  Settings s = toy_settings(3, 1);
  train(s, "dim", dir / "data", dir / "run");
  DimEnsemble ens(load_members(dir / "run"));
  ToyObservation o = toy_observation(dir / "data", 1, 25, s.dim);  // 2 m/s
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
  EXPECT_NEAR(implied_speed(q.z, 5, 0.1), q.z[0].norm().item<double>() / 0.5, 1e-9);
  EXPECT_GE(implied_speed(q.z, 5, 0.1), implied_speed(mean, 5, 0.1));
}

TEST_F(DimTest, RipWorstCaseIsTheMinimumOfItsMembers) {
  TempDir dir("cd-dim");
  write_toy_folder(dir / "data", 5);
  Settings s = toy_settings(2, 3);
  TrainSummary sum = train(s, "rip", dir / "data", dir / "run");
  EXPECT_EQ(sum.epochs_done, 6);  // 3 members x 2 epochs
  DimRun run = *read_dim_run(dir / "run");
  ASSERT_EQ(run.members.size(), 3u);
  // Bootstrap resamples differ between members (with this seed).
  for (const DimMember& m : run.members) {
    EXPECT_EQ(m.episodes.size(), 4u);  // as many draws as training episodes
    EXPECT_EQ(m.train_samples, 4 * (kToyFrames - 20));
  }
  EXPECT_FALSE(run.members[0].episodes == run.members[1].episodes &&
               run.members[1].episodes == run.members[2].episodes);
  std::vector<DimNet> nets = load_members(dir / "run");
  DimEnsemble ens(nets);
  ToyObservation o = toy_observation(dir / "data", 0, 10, s.dim);
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

TEST_F(DimTest, SameSeedSameBytesAndInterruptedMembersAreRetrained) {
  TempDir dir("cd-dim");
  write_toy_folder(dir / "data", 4);
  Settings s = toy_settings(2, 2);
  train(s, "rip", dir / "data", dir / "a");
  train(s, "rip", dir / "data", dir / "b");
  for (const char* f : {"member_0.pt", "member_1.pt"})
    EXPECT_EQ(test::read_text(dir / "a" + "/" + f), test::read_text(dir / "b" + "/" + f)) << f;
  EXPECT_NE(test::read_text(dir / "a/member_0.pt"), test::read_text(dir / "a/member_1.pt"));
  Settings other = s;
  other.train.seed = 8;
  train(other, "rip", dir / "data", dir / "c");
  EXPECT_NE(test::read_text(dir / "a/member_0.pt"), test::read_text(dir / "c/member_0.pt"));

  // A finished folder: nothing left to train.
  TrainSummary again = train(s, "rip", dir / "data", dir / "a");
  EXPECT_EQ(again.samples_per_s, 0.0);
  EXPECT_EQ(again.resumed_from, 4);
  // Member 1 interrupted (never marked finished): retrained alone, to the same bytes.
  json rec = json::parse(test::read_text(dir / "b/dim.json"));
  rec["members"][1]["finished"] = false;
  test::write_text(dir / "b/dim.json", rec.dump(2) + "\n");
  test::write_text(dir / "b/member_1.pt", "half-written");
  EXPECT_THROW(DimPlanner(dir / "b", "rip"), DataError);  // an unfinished run is no agent
  TrainSummary resumed = train(s, "rip", dir / "data", dir / "b");
  EXPECT_EQ(resumed.resumed_from, 2);
  EXPECT_GT(resumed.samples_per_s, 0.0);
  for (const char* f : {"member_0.pt", "member_1.pt"})
    EXPECT_EQ(test::read_text(dir / "a" + "/" + f), test::read_text(dir / "b" + "/" + f)) << f;
  // Other settings or another method into the same folder: refused.
  Settings wider = s;
  wider.dim.hidden = 64;
  EXPECT_THROW(train(wider, "rip", dir / "data", dir / "a"), ConfigError);
  EXPECT_THROW(train(s, "dim", dir / "data", dir / "a"), ConfigError);
  EXPECT_EQ(test::split_lines(test::read_text(dir / "b/metrics.jsonl")).size(), 4u);
  EXPECT_THROW(DimPlanner(dir / "missing", "rip"), DataError);
}

// ---- through the binary ----------------------------------------------------------------

void expect_one_line_error(const test::CommandResult& r, const std::string& needle) {
  EXPECT_TRUE(r.exited && r.exit_code == 1) << r.describe();
  EXPECT_EQ(test::split_lines(r.err).size(), 1u) << r.describe();
  EXPECT_NE(r.err.find(needle), std::string::npos) << r.describe();
}

TEST(DimCli, WrongFoldersGiveOneLineErrors) {
  TempDir dir("cd-dim");
  write_toy_folder(dir / "data", 3);
  const std::string cfg = dir / "c.toml";
  test::write_text(cfg, "[train]\nepochs = 1\nthreads = 1\nbatch_size = 16\n"
                        "[dim]\nfeatures = 16\nhidden = 16\nensemble = 2\n");
  auto t = test::run_cli({"train", "--config", cfg, "--method", "dim", "--data", dir / "data",
                          "--out", dir / "dim"});
  ASSERT_EQ(t.exit_code, 0) << t.describe();
  EXPECT_NE(t.out.find("trained dim"), std::string::npos) << t.out;
  auto again = test::run_cli({"train", "--config", cfg, "--method", "dim", "--data",
                              dir / "data", "--out", dir / "dim"});
  ASSERT_EQ(again.exit_code, 0) << again.describe();
  EXPECT_NE(again.out.find("nothing left to train"), std::string::npos) << again.out;
  // dim trains one model whatever dim.ensemble says.
  EXPECT_EQ(json::parse(test::read_text(dir / "dim/dim.json"))["members"].size(), 1u);

  expect_one_line_error(test::run_cli({"train", "--config", cfg, "--method", "rip", "--data",
                                       dir / "data", "--out", dir / "dim"}),
                        "method 'dim'");
  test::fs::create_directories(dir / "bc");
  test::write_text(dir / "bc/checkpoint.json", R"({"method": "bc-oh"})");
  expect_one_line_error(test::run_cli({"train", "--config", cfg, "--method", "dim", "--data",
                                       dir / "data", "--out", dir / "bc"}),
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

// Collect two real episodes, train a tiny dim, drive it on a one-task suite in the simulator.
TEST(DimCli, TrainsAndDrivesInTheSimulator) {
  TempDir dir("cd-dim");
  const std::string cfg = test::write_test_config(
      dir, "empty",
      "\n[train]\nepochs = 1\nmax_samples = 400\nthreads = 1\nbatch_size = 32\n"
      "\n[dim]\nfeatures = 32\nhidden = 32\nplan_iterations = 10\n");
  auto c = test::run_cli({"collect", "--config", cfg, "--out", dir / "data"});
  ASSERT_EQ(c.exit_code, 0) << c.describe();
  auto t = test::run_cli({"train", "--config", cfg, "--method", "dim", "--data", dir / "data",
                          "--out", dir / "run"});
  ASSERT_EQ(t.exit_code, 0) << t.describe();
  auto s = test::run_cli({"suite", "--town", "town-a", "--traffic", "empty", "--tasks", "1",
                          "--trials", "1", "--seed", "3", "--min-route", "100", "--max-route",
                          "150", "--scenarios", "route", "--out", dir / "suite.json"});
  ASSERT_EQ(s.exit_code, 0) << s.describe();
  auto e = test::run_cli({"eval", "--config", cfg, "--agent", "dim", "--checkpoint", dir / "run",
                          "--suite", dir / "suite.json", "--workers", "1", "--out", dir / "eval",
                          "--quiet"});
  ASSERT_EQ(e.exit_code, 0) << e.describe();
  EXPECT_NE(e.out.find("| dim |"), std::string::npos) << e.out;
  json res = json::parse(test::read_text(dir / "eval/results.json"));
  EXPECT_EQ(res["agent"], "dim");
  ASSERT_EQ(res["episodes"].size(), 1u);
  EXPECT_EQ(res["summary"]["infrastructure_failures"], 0);
  // It moved: the plan's speed reached the vehicle.
  EXPECT_GT(res["episodes"][0]["route_completion"].get<double>(), 0.0) << res.dump();
}

}  // namespace
}  // namespace cd
