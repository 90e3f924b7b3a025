#include "agents/observation_feed.hpp"

#include <algorithm>

#include "world/world.hpp"

namespace cd {

ObservationFeed::ObservationFeed(const World& world, const Agent& agent, const SensorShift* shift,
                                 uint64_t episode_key)
    : world_(world),
      shift_(shift),
      episode_key_(episode_key),
      k_(std::max(1, agent.history())),
      stride_(std::max(1, agent.history_stride())),
      frames_(agent.uses_frames()),
      goal_distance_(agent.goal_distance()),
      span_(static_cast<size_t>((k_ - 1) * stride_ + 1)),
      frame_bytes_(world.frame_format().bytes()),
      ring_(frames_ ? span_ * frame_bytes_ : 0) {
  if (shift_) require_bev_for_shift(world.frame_format().view);
  const FrameFormat& f = world.frame_format();
  obs_.view = f.view.c_str();
  obs_.channels = f.channels;
  obs_.height = f.height;
  obs_.width = f.width;
  obs_.frames.resize(frames_ ? k_ : 0);
}

void ObservationFeed::push() {
  if (!frames_) return;
  uint8_t* frame = ring_.data() + (rendered_ % span_) * frame_bytes_;
  if (shift_)
    render_sensor(world_.renderer(), world_.scene(), shift_,
                  sensor_frame_key(shift_->seed, episode_key_, rendered_), frame);
  else
    world_.render(frame);
  ++rendered_;
}

const Observation& ObservationFeed::observe() {
  for (int j = 0; j < static_cast<int>(obs_.frames.size()); ++j) {
    const size_t idx = rendered_ - 1 - static_cast<size_t>((k_ - 1 - j) * stride_);
    obs_.frames[j] = ring_.data() + (idx % span_) * frame_bytes_;
  }
  const EgoState& ego = world_.ego();
  obs_.speed = ego.speed;
  obs_.command = world_.command();
  obs_.x = ego.pose.pos.x;
  obs_.y = ego.pose.pos.y;
  obs_.heading = ego.pose.heading;
  if (goal_distance_ > 0) {
    const Vec2 g = to_ego_frame(ego.pose, world_.path_point(goal_distance_));
    obs_.goal_x = g.x;
    obs_.goal_y = g.y;
  }
  return obs_;
}

}  // namespace cd
