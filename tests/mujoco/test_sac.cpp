// The SAC state expert (src/mujoco/sac): same seed same bytes, the saved policy is the one
// whose evaluation the record reports (replayed here through PolicyExpert on the same seeded
// episode), the policy input drops the root position, the expert a config selects, and the
// errors of a missing or mismatched policy file.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <string>

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

}  // namespace
}  // namespace cd::mj
