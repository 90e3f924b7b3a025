// Which expert a MuJoCo-Image command gets (mj::expert_policies_for): the shipped SAC experts
// by default, the planner when asked for by name or by tuning it, a folder when named.
#include <gtest/gtest.h>

#include <string>

#include "mujoco/expert.hpp"

namespace cd {
namespace {

TEST(MujocoExpertChoice, ShippedByDefaultPlannerWhenAskedAFolderWhenNamed) {
  const std::string shipped = std::string(CD_SOURCE_DIR) + "/experts";
  const mj::PlannerOptions untuned;
  for (const char* env : {"halfcheetah", "hopper", "ant", "reacher", "humanoid"})
    EXPECT_EQ(mj::expert_policies_for("", env, untuned), shipped) << env;
  EXPECT_EQ(mj::expert_policies_for("", "nonesuch", untuned), "") << "no shipped expert";
  EXPECT_EQ(mj::expert_policies_for("planner", "hopper", untuned), "");
  EXPECT_EQ(mj::expert_policies_for("my/experts", "hopper", untuned), "my/experts");
  mj::PlannerOptions tuned;
  tuned.samples = 8;
  EXPECT_EQ(mj::expert_policies_for("", "hopper", tuned), "") << "a tuned planner is asked for";
  tuned = {};
  tuned.smoothing = 0.5;
  EXPECT_EQ(mj::expert_policies_for("", "hopper", tuned), "");
  EXPECT_EQ(mj::expert_policies_for("my/experts", "hopper", tuned), "my/experts");
}

}  // namespace
}  // namespace cd
