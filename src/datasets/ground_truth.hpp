#pragma once
// Ground-truth causes of a recorded episode as the analyses read them.
#include <string>
#include <vector>

#include "datasets/episode_set.hpp"

namespace cd {

// The ground-truth causes the selected latents are compared with (names, in this order):
// lead_distance (min(d, 60), 60 without a leader), lead_present, red_light (tl_state red or
// yellow and tl_distance < 30), path_free, ped_on_path. NaN when the episode lacks the series.
const std::vector<std::string>& ground_truth_names();
double ground_truth_value(const PackedEpisode& ep, const std::string& name, int t);

}  // namespace cd
