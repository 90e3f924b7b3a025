#include "datasets/trajectory.hpp"

#include <algorithm>

#include "core/geometry.hpp"

namespace cd {

void dim_sample_positions(const PackedEpisode& e, int t, const DimSettings& d, float* past,
                          float* future) {
  const float* pose = e.pose.data();
  Pose2 origin{{pose[3 * t], pose[3 * t + 1]}, pose[3 * t + 2]};
  // An augmented frame shows the scene from a shifted, turned pose: its positions are in that
  // pose's frame, so the expert's future path seen from there leads back onto the lane.
  if (!e.augment.empty())
    origin = shifted_pose(origin, e.augment[2 * static_cast<size_t>(t)],
                          e.augment[2 * static_cast<size_t>(t) + 1]);
  auto put = [&](int s, float* out) {
    const Vec2 p = to_ego_frame(origin, Vec2{pose[3 * s], pose[3 * s + 1]});
    out[0] = static_cast<float>(p.x);
    out[1] = static_cast<float>(p.y);
  };
  for (int k = 0; k < d.past; ++k) put(std::max(0, t - (k + 1) * d.waypoint_step), past + 2 * k);
  for (int k = 0; k < d.horizon; ++k) put(t + (k + 1) * d.waypoint_step, future + 2 * k);
}

}  // namespace cd
