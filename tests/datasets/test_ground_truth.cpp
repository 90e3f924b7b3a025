// The ground-truth causes the cim runs are compared with (datasets/ground_truth), and the
// Pearson correlation of that comparison.
#include "datasets/ground_truth.hpp"

#include <gtest/gtest.h>

#include <cmath>

#include "causal/cause_selection.hpp"
#include "datasets/episode_set.hpp"

namespace cd {
namespace {

TEST(CimGroundTruth, DerivedCausesAndPearson) {
  PackedEpisode ep;
  ep.frames = 3;
  ep.causes["lead_distance"] = {10, 100, 5};
  ep.causes["lead_present"] = {1, 1, 0};
  ep.causes["tl_state"] = {1, 2, 1};
  ep.causes["tl_distance"] = {10, 40, 29};
  EXPECT_DOUBLE_EQ(ground_truth_value(ep, "lead_distance", 0), 10);
  EXPECT_DOUBLE_EQ(ground_truth_value(ep, "lead_distance", 1), 60);  // clamped
  EXPECT_DOUBLE_EQ(ground_truth_value(ep, "lead_distance", 2), 60);  // no leader
  EXPECT_DOUBLE_EQ(ground_truth_value(ep, "red_light", 0), 1);
  EXPECT_DOUBLE_EQ(ground_truth_value(ep, "red_light", 1), 0);  // too far
  EXPECT_DOUBLE_EQ(ground_truth_value(ep, "red_light", 2), 1);
  EXPECT_TRUE(std::isnan(ground_truth_value(ep, "ped_on_path", 0)));
  EXPECT_NEAR(pearson({1, 2, 3, 4}, {2, 4, 6, 8}), 1.0, 1e-12);
  EXPECT_NEAR(pearson({1, 2, 3, 4}, {4, 3, 2, 1}), -1.0, 1e-12);
  EXPECT_TRUE(std::isnan(pearson({1, 1, 1}, {1, 2, 3})));
}

}  // namespace
}  // namespace cd
