#pragma once
// The expert: a rule-based autopilot with privileged state. It can be asked for its action at
// any state of the ego (DAgger relabelling, noise injection): it reads only the World's
// current ground truth, never its own history.
#include "expert/expert_settings.hpp"
#include "world/world.hpp"

namespace cd {

class Autopilot {
 public:
  explicit Autopilot(const ExpertSettings& s) : s_(s) {}

  // The speed the expert wants now: the tightest of cruise, turn, leader, light, yield and
  // pedestrian limits, each a braking profile that stops at the right place.
  double target_speed(const World& w) const;

  // Throttle and brake that track the target speed under the ego's vehicle model, and with
  // ego.lateral = "free" the steer of a path tracker along the route's lane plan.
  Control act(const World& w) const;

 private:
  struct Plan {
    double speed = 0;     // target speed now
    double stop = 1e9;    // m to the nearest place the ego must stand still
  };
  Plan plan(const World& w) const;
  ExpertSettings s_;
};

// Pure pursuit: the steer in [-1, 1] that puts the rear axle of an ego at `pose` (box centre
// midway between the axles) on a circle through `target` (the kinematic bicycle's yaw rate is
// v_rear tan(angle) / L, so angle = atan(2 L y / d^2) for the target at (x, y) from the rear
// axle, d its distance).
double pursuit_steer(const Pose2& pose, Vec2 target, const EgoSettings& ego);

// The steer that tracks the route path: pure pursuit towards the path point a speed-dependent
// distance ahead of the front bumper. The expert's, that of agents which only learn a speed (cs)
// in ego.lateral = "free", and, from a pose other than the ego's, the corrective label of the
// lateral augmentation (collect.augment).
double steer_towards_path(const World& w);
double steer_towards_path(const World& w, const Pose2& pose);

}  // namespace cd
