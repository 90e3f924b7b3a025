#pragma once
// Trajectory samples of the imitative model (dim, rip) from an episode's poses.
#include "app/settings.hpp"
#include "datasets/episode_set.hpp"

namespace cd {

// A training sample's positions from an episode's poses: past[2k], past[2k+1] = position at
// t - (k+1)*waypoint_step (clamped at the episode's first step), future likewise at
// t + (k+1)*waypoint_step, both in the ego frame of step t (x forward, y left, m): the frame
// of the pose its image was rendered from, which for an augmented frame (collect.augment) is
// the true pose shifted and turned (shifted_pose), so that its future leads back to the lane.
// Requires t + horizon*step < T.
void dim_sample_positions(const PackedEpisode& e, int t, const DimSettings& d, float* past,
                          float* future);

}  // namespace cd
