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

// The steer in [-1, 1] that tracks the route path (pure pursuit from the rear axle): the
// expert's, and that of agents which only learn a speed (cs) in ego.lateral = "free".
double steer_towards_path(const World& w);

}  // namespace cd
