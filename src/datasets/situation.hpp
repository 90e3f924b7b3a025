#pragma once
// What the expert is doing at a recorded step, from the recorded causes and its motion (SPEC
// section 10): the situations the imitation diagnosis splits frames by and the balanced
// sample weights of training (train.situation_weights) count. Acceleration = (speed[t+1] -
// speed[t]) / dt, the last step backwards. A step may fall in several situations (a car
// following its leader at a steady 8 m/s is cruising and following) or in none; "all" holds
// every step:
//   standing_free     speed < 0.5, path free, no red light ahead within stopping distance
//   starting          speed < 3, accelerating (> 0.5 m/s^2), path free
//   cruising          speed >= 3, |acceleration| < 0.5
//   slowing_red       decelerating (< -0.5) with a red light ahead within stopping distance
//   slowing_other     decelerating with no red light ahead (a leader, a yield, a turn)
//   following         moving (>= 0.5) with a leader within 30 m
//   standing_blocked  speed < 0.5 behind a leader within 30 m or a red light ahead
// "A red light ahead within stopping distance": tl_state red or yellow and tl_distance <=
// speed^2 / (2 * 3 m/s^2, the expert's comfort deceleration) + 10 m.
#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "datasets/episode_set.hpp"

namespace cd {

// The thresholds above, as values (a test or a user may tighten them).
struct SituationRules {
  double standing_below = 0.5;    // m/s
  double starting_below = 3.0;    // m/s
  double accel_threshold = 0.5;   // m/s^2
  double lead_within = 30.0;      // m
  double red_decel = 3.0;         // m/s^2: stopping distance v^2 / (2 red_decel) ...
  double red_margin = 10.0;       // m: ... plus this
};

enum Situation : int {
  kAllFrames = 0,
  kStandingFree,
  kStarting,
  kCruising,
  kSlowingRed,
  kSlowingOther,
  kFollowing,
  kStandingBlocked,
  kSituationCount
};
const std::vector<std::string>& situation_names();  // indexed by Situation

// The cause series the situations read (path_free, tl_state, tl_distance, lead_present,
// lead_distance), and whether the first episode of a driving data folder records them all
// (collect does; reads that one file).
const std::vector<std::string>& situation_causes();
bool has_situation_causes(const std::map<std::string, std::vector<float>>& causes);
bool records_situation_causes(const std::string& data_dir);

// The situations of step t of a driving episode, as a bit mask (bit s = Situation s; kAllFrames
// always set). Throws DataError naming the file when a needed cause series is missing.
uint32_t situations_at(const PackedEpisode& ep, int t, double dt, const SituationRules& rules = {});

}  // namespace cd

namespace cd {

// The one class of a step for balancing (the first present of: starting, standing_free,
// slowing_red, slowing_other, standing_blocked, following, cruising; kAllFrames when none):
// the rare transitions win over the states they interrupt.
int situation_class(uint32_t mask);

// Balanced weights of samples whose classes are `classes` (values 0 .. kSituationCount-1):
// w_c = N / (C n_c) with N samples and C classes present, at most max_weight, then all scaled
// so that their mean is 1. Empty in, empty out.
std::vector<float> balanced_weights(const std::vector<int>& classes, double max_weight);

}  // namespace cd
