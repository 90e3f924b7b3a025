// The SAC state expert (src/mujoco/sac): same seed same bytes, the saved policy is the one
// whose evaluation the record reports (replayed here through PolicyExpert on the same seeded
// episode), the policy input drops the root position, the expert a config selects, and the
// errors of a missing or mismatched policy file.
// needs: mujoco
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "../support/test_support.hpp"
#include "core/error.hpp"
#include "core/rng.hpp"
#include "mujoco/env.hpp"
#include "mujoco/sac.hpp"

namespace cd::mj {
namespace {

SacOptions tiny(uint64_t seed) {
  SacOptions o;
  o.steps = 400;
  o.start_steps = 200;
  o.batch = 32;
  o.hidden = 16;
  o.eval_every = 200;
  o.eval_episodes = 1;
  o.seed = seed;
  return o;
}

std::string bytes(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(f), {}};
}

TEST(Sac, SameSeedSameBytesAndAnotherSeedDiffers) {
  test::TempDir dir;
  train_sac("reacher", tiny(5), dir / "a.pt");
  train_sac("reacher", tiny(5), dir / "b.pt");
  train_sac("reacher", tiny(6), dir / "c.pt");
  ASSERT_FALSE(bytes(dir / "a.pt").empty());
  EXPECT_TRUE(bytes(dir / "a.pt") == bytes(dir / "b.pt"));  // (not printed: binary)
  EXPECT_FALSE(bytes(dir / "a.pt") == bytes(dir / "c.pt"));
  const auto ja = nlohmann::json::parse(bytes(dir / "a.json"));
  const auto jb = nlohmann::json::parse(bytes(dir / "b.json"));
  EXPECT_EQ(ja["evaluations"].size(), 2u);
  EXPECT_EQ(ja["best"], jb["best"]);
}

TEST(Sac, TheSavedPolicyIsTheBestEvaluatedOneAndPolicyExpertReplaysIt) {
  test::TempDir dir;
  const SacOptions o = tiny(9);
  const SacReport r = train_sac("reacher", o, dir / "reacher.pt");
  ASSERT_EQ(r.evaluations.size(), 2u);
  double best = -1e300;
  for (const SacEvaluation& e : r.evaluations) best = std::max(best, e.mean_return);
  EXPECT_DOUBLE_EQ(r.best.mean_return, best);

  // The evaluation episode: seed derive_seed(derive_seed(seed, 3), 0), deterministic actions.
  PolicyExpert expert(dir / "reacher.pt", "reacher");
  Env env("reacher");
  env.reset(derive_seed(derive_seed(o.seed, 3), 0));
  double ret = 0;
  const std::vector<double> low = env.action_low(), high = env.action_high();
  for (int t = 0; t < env.max_steps(); ++t) {
    const std::vector<double> a = expert.act(env.state());
    ASSERT_EQ(a.size(), 2u);
    for (size_t i = 0; i < a.size(); ++i) {
      EXPECT_GE(a[i], low[i]);
      EXPECT_LE(a[i], high[i]);
    }
    const StepResult s = env.step(a);
    ret += s.reward;
    if (s.terminated || s.truncated) break;
  }
  EXPECT_NEAR(ret, r.best.mean_return, 1e-6 * std::max(1.0, std::abs(ret)));
  // Asked twice at one state, a deterministic expert answers the same.
  EXPECT_EQ(expert.act(env.state()), expert.act(env.state()));
  EXPECT_NE(expert.describe().find("sac"), std::string::npos);
}

TEST(Sac, ThePolicyDoesNotSeeTheRootPosition) {
  Env env("halfcheetah");
  env.reset(1);
  std::vector<double> s = env.state();
  const std::vector<float> x = policy_input(env.spec(), env.qpos_dim(), s);
  ASSERT_EQ(x.size(), s.size() - 1);  // halfcheetah drops x
  EXPECT_FLOAT_EQ(x[0], static_cast<float>(s[1]));
  s[0] += 100.0;
  EXPECT_EQ(policy_input(env.spec(), env.qpos_dim(), s), x);
  Env ant("ant");
  EXPECT_EQ(policy_input(ant.spec(), ant.qpos_dim(), ant.state()).size(),
            static_cast<size_t>(ant.state_dim() - 2));
}

TEST(Sac, MakeExpertPicksThePolicyFolderOrThePlanner) {
  test::TempDir dir;
  train_sac("reacher", tiny(2), dir / "reacher.pt");
  EXPECT_NE(make_expert("reacher", {}, dir.path())->describe().find("sac"), std::string::npos);
  EXPECT_EQ(make_expert("reacher", {}, "")->describe().find("sac"), std::string::npos);
  // The folder holds no hopper policy: one line naming the file.
  try {
    make_expert("hopper", {}, dir.path());
    FAIL() << "expected DataError";
  } catch (const DataError& e) {
    EXPECT_NE(std::string(e.what()).find(dir / "hopper.pt"), std::string::npos) << e.what();
  }
}

TEST(Sac, AMismatchedOrCorruptPolicyFileIsADataError) {
  test::TempDir dir;
  train_sac("reacher", tiny(2), dir / "reacher.pt");
  EXPECT_THROW(PolicyExpert(dir / "reacher.pt", "hopper"), DataError);
  std::ofstream(dir / "bad.pt") << "not a policy";
  EXPECT_THROW(PolicyExpert(dir / "bad.pt", "reacher"), DataError);
  SacOptions bad = tiny(1);
  bad.start_steps = bad.steps + 1;
  EXPECT_THROW(train_sac("reacher", bad, dir / "x.pt"), ConfigError);
  EXPECT_THROW(train_sac("walker", tiny(1), dir / "x.pt"), ConfigError);
}

// A run stopped after an evaluation (here: its log line throws) resumes from its resume file to
// the same policy bytes and evaluations as a run never stopped; the file is gone once finished.
// The resume file refuses other settings, a finished run is kept, an existing policy is never
// overwritten by another run, and a corrupt resume file is a DataError naming it.
TEST(Sac, AnInterruptedRunResumesToTheSameBytes) {
  test::TempDir dir;
  SacOptions o = tiny(3);
  o.steps = 600;
  o.start_steps = 100;
  const SacReport whole = train_sac("reacher", o, dir / "whole.pt");
  ASSERT_EQ(whole.evaluations.size(), 3u);
  EXPECT_FALSE(std::filesystem::exists(sac_resume_path(dir / "whole.pt")));

  struct Stopped {};
  const std::string cut = dir / "cut.pt";
  EXPECT_THROW(train_sac("reacher", o, cut,
                         [](const std::string& line) {
                           if (line.find("] 400/600 steps") != std::string::npos) throw Stopped{};
                         }),
               Stopped);
  ASSERT_TRUE(std::filesystem::exists(sac_resume_path(cut)));
  SacOptions other = o;
  other.lr = 1e-3;
  try {
    train_sac("reacher", other, cut);
    ADD_FAILURE() << "a resume file of other settings was used";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find(sac_resume_path(cut)), std::string::npos) << e.what();
  }

  std::vector<std::string> lines;
  const SacReport resumed = train_sac("reacher", o, cut, [&](const std::string& l) { lines.push_back(l); });
  ASSERT_FALSE(lines.empty());
  EXPECT_NE(lines[0].find("resuming"), std::string::npos) << lines[0];
  EXPECT_NE(lines[0].find("at step 400/600"), std::string::npos) << lines[0];
  EXPECT_TRUE(bytes(dir / "whole.pt") == bytes(cut));  // (not printed: binary)
  ASSERT_EQ(resumed.evaluations.size(), whole.evaluations.size());
  for (size_t i = 0; i < whole.evaluations.size(); ++i) {
    EXPECT_EQ(resumed.evaluations[i].steps, whole.evaluations[i].steps);
    EXPECT_EQ(resumed.evaluations[i].mean_return, whole.evaluations[i].mean_return) << i;
  }
  EXPECT_EQ(resumed.episodes, whole.episodes);
  EXPECT_FALSE(std::filesystem::exists(sac_resume_path(cut)));

  // Finished: the same command trains nothing and returns the record.
  lines.clear();
  const SacReport again = train_sac("reacher", o, cut, [&](const std::string& l) { lines.push_back(l); });
  ASSERT_EQ(lines.size(), 1u);
  EXPECT_NE(lines[0].find("kept"), std::string::npos) << lines[0];
  EXPECT_EQ(again.best.steps, whole.best.steps);
  EXPECT_EQ(again.best.mean_return, whole.best.mean_return);
  // Another run into the finished file: refused, the policy untouched.
  const std::string before = bytes(cut);
  EXPECT_THROW(train_sac("reacher", other, cut), ConfigError);
  EXPECT_TRUE(bytes(cut) == before);

  std::ofstream(sac_resume_path(dir / "x.pt")) << "not a resume file";
  try {
    train_sac("reacher", o, dir / "x.pt");
    ADD_FAILURE() << "a corrupt resume file was accepted";
  } catch (const DataError& e) {
    EXPECT_NE(std::string(e.what()).find("x.pt.resume"), std::string::npos) << e.what();
  }
}

// An env restored from a snapshot steps on exactly as the original (set_state, which clears
// the solver's warm start, need not).
TEST(Sac, EnvSnapshotContinuesBitForBit) {
  Env a("hopper"), b("hopper");
  a.reset(5);
  Rng rng(7);
  auto action = [&] {
    std::vector<double> u(static_cast<size_t>(a.action_dim()));
    for (double& x : u) x = rng.uniform(-1.0, 1.0);
    return u;
  };
  for (int t = 0; t < 20; ++t) a.step(action());
  b.reset(99);
  b.restore(a.snapshot());
  EXPECT_EQ(b.steps(), a.steps());
  for (int t = 0; t < 30; ++t) {
    const std::vector<double> u = action();
    const StepResult ra = a.step(u), rb = b.step(u);
    ASSERT_EQ(ra.reward, rb.reward) << t;
    ASSERT_TRUE(a.state() == b.state()) << t;
  }
  EXPECT_THROW(b.restore(std::vector<double>(3, 0.0)), SimError);
}

}  // namespace
}  // namespace cd::mj
