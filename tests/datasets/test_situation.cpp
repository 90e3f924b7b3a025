// Situations of recorded steps (datasets/situation): hand-made steps against the rules
// written out.
#include "datasets/situation.hpp"

#include <gtest/gtest.h>

#include "../support/situation_masks.hpp"
#include "core/error.hpp"

namespace cd {
namespace {

using test::situation_bits;

// Ten steps, each built to fall in known situations (dt 0.1; acceleration = next speed minus
// this one over dt; the last step looks back).
PackedEpisode hand_made_episode() {
  PackedEpisode ep;
  ep.file = "episode_hand.h5";
  ep.frames = 10;
  ep.speed = {0.0f, 0.0f, 0.1f, 2.0f, 5.0f, 5.0f, 4.5f, 0.2f, 0.2f, 0.2f};
  // speed[t+1] of step 3 is 5.0 (accel 30): keep step 3 "starting" with v < 3.
  ep.causes["path_free"] = {1, 1, 1, 1, 1, 1, 1, 0, 1, 0};
  ep.causes["tl_state"] = {0, 0, 0, 0, 0, 1, 1, 1, 2, 0};
  ep.causes["tl_distance"] = {100, 100, 100, 100, 100, 12, 20, 3, 8, 100};
  ep.causes["lead_present"] = {0, 0, 0, 1, 1, 0, 0, 0, 0, 0};
  ep.causes["lead_distance"] = {100, 100, 100, 25, 40, 100, 100, 100, 100, 100};
  return ep;
}

TEST(Situations, SituationsOfHandMadeStepsFollowTheRules) {
  PackedEpisode ep = hand_made_episode();
  const std::vector<uint32_t> expected = {
      situation_bits({kStandingFree}),                // 0: stands, free, stays
      situation_bits({kStandingFree, kStarting}),     // 1: stands, accelerates (1 m/s^2)
      situation_bits({kStandingFree, kStarting}),     // 2: 0.1 m/s, accelerating
      situation_bits({kStarting, kFollowing}),        // 3: 2 m/s, accelerating, leader 25 m
      situation_bits({kCruising}),                    // 4: 5 m/s, leader at 40 m is beyond 30
      situation_bits({kSlowingRed}),                  // 5: red 12 m <= 25/6 + 10
      situation_bits({kSlowingOther}),                // 6: red 20 m > 4.5^2/6 + 10 = 13.4
      situation_bits({kStandingBlocked}),             // 7: red 3 m, path blocked
      situation_bits({kStandingBlocked}),             // 8: yellow 8 m counts as red, path free
      situation_bits({}),                             // 9: stands, path blocked by nothing it names
  };
  for (int t = 0; t < ep.frames; ++t)
    EXPECT_EQ(situations_at(ep, t, 0.1), expected[t]) << "step " << t;
  // The thresholds are settings: a 3 m/s^2 threshold makes step 1 no start.
  SituationRules strict;
  strict.accel_threshold = 3.0;
  EXPECT_EQ(situations_at(ep, 1, 0.1, strict), situation_bits({kStandingFree}));
}

TEST(Situations, MissingCauseIsADataErrorNamingTheFile) {
  PackedEpisode ep = hand_made_episode();
  ep.causes.erase("tl_state");
  try {
    situations_at(ep, 0, 0.1);
    FAIL() << "no error";
  } catch (const DataError& e) {
    EXPECT_NE(std::string(e.what()).find("episode_hand.h5 has no causes/tl_state"),
              std::string::npos)
        << e.what();
  }
}

TEST(Situations, ClassIsTheFirstRareTransition) {
  EXPECT_EQ(situation_class(situation_bits({kCruising, kFollowing})), kFollowing);
  EXPECT_EQ(situation_class(situation_bits({kStandingFree, kStarting})), kStarting);
  EXPECT_EQ(situation_class(situation_bits({kSlowingRed})), kSlowingRed);
  EXPECT_EQ(situation_class(situation_bits({kStandingBlocked, kFollowing})), kStandingBlocked);
  EXPECT_EQ(situation_class(situation_bits({})), kAllFrames);
}

TEST(Situations, BalancedWeightsByHand) {
  // One start, three cruising steps: N = 4, C = 2; w = 4 / (2 * 1) = 2 and 4 / (2 * 3) = 2/3,
  // whose mean is already 1.
  const std::vector<int> c = {kStarting, kCruising, kCruising, kCruising};
  std::vector<float> w = balanced_weights(c, 10.0);
  ASSERT_EQ(w.size(), 4u);
  EXPECT_NEAR(w[0], 2.0, 1e-6);
  for (int i = 1; i < 4; ++i) EXPECT_NEAR(w[i], 2.0 / 3.0, 1e-6);
  // Capped at 1.5: 1.5 and 2/3 sum to 3.5 over 4 samples, so both scale by 4 / 3.5.
  w = balanced_weights(c, 1.5);
  EXPECT_NEAR(w[0], 1.5 * 4 / 3.5, 1e-6);
  EXPECT_NEAR(w[1], 2.0 / 3.0 * 4 / 3.5, 1e-6);
  // One class: every weight 1.
  EXPECT_EQ(balanced_weights({kCruising, kCruising}, 10.0), (std::vector<float>{1.0f, 1.0f}));
  EXPECT_TRUE(balanced_weights({}, 10.0).empty());
}

}  // namespace
}  // namespace cd
