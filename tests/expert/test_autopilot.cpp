// The expert (expert/autopilot) in closed loop in the live world: it reaches its goal on every
// built-in town, with regular traffic, never running a red light.
//
// libsumo runs one simulation per process and ctest runs every TEST in its own process, so
// each TEST below creates at most one World.
// needs: sumo
#include "expert/autopilot.hpp"

#include <gtest/gtest.h>

#include <cstdint>
#include <string>

#include "../support/test_support.hpp"
#include "app/settings.hpp"
#include "world/world.hpp"

namespace cd {
namespace {

using test::TempDir;

// The test config (town-a, short warm-up, short routes) read back through load_settings.
Settings test_settings(const std::string& traffic = "empty") {
  TempDir dir("cdtest-expert");
  return load_settings(test::write_test_config(dir, traffic));
}

// The expert closed loop on a tiny suite of each built-in town, with regular traffic.
void expect_expert_reaches_goals(const std::string& town) {
  Settings s = test_settings("regular");
  s.world.town = town;
  World w(s);
  Autopilot expert(s.expert);
  for (uint64_t seed = 0; seed < 4; ++seed) {
    Task task = w.sample_task(seed, 150, 250);
    w.reset(task);
    StepResult r;
    int steps = 0;
    for (; steps < 10000 && r.outcome == Outcome::Running; ++steps) r = w.step(expert.act(w));
    EXPECT_EQ(r.outcome, Outcome::Success)
        << town << " seed " << seed << ": " << outcome_name(r.outcome) << " "
        << r.collided_with << " after " << steps << " steps";
    EXPECT_EQ(w.counters().red_light_violations, 0) << town << " seed " << seed;
    EXPECT_GT(w.counters().distance, task.route_length - 1.0) << town << " seed " << seed;
  }
}

TEST(ExpertClosedLoop, TownA) { expect_expert_reaches_goals("town-a"); }
TEST(ExpertClosedLoop, TownB) { expect_expert_reaches_goals("town-b"); }
TEST(ExpertClosedLoop, TownC) { expect_expert_reaches_goals("town-c"); }

}  // namespace
}  // namespace cd
