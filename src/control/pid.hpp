#pragma once
// Speed controller shared by every agent that outputs a target speed (cs, the target-speed
// head of bc-so/bc-oh, CIM): PID on the speed error gives an acceleration command, and the
// ego's vehicle model turns it into throttle if positive, brake otherwise (seed 000, eq. 2).
#include <algorithm>

#include "app/settings.hpp"
#include "world/ego_model.hpp"

namespace cd {

class SpeedPid {
 public:
  SpeedPid(const ControlSettings& s, const EgoModel& model, double dt)
      : s_(s), model_(model), dt_(dt) {}

  void reset() {
    integral_ = 0;
    prev_error_ = 0;
    first_ = true;
  }

  Control control(double target_speed, double speed) {
    double e = target_speed - speed;
    double de = first_ ? 0.0 : (e - prev_error_) / dt_;
    first_ = false;
    prev_error_ = e;
    integral_ = std::clamp(integral_ + e * dt_, -s_.integral_limit, s_.integral_limit);
    double a = s_.kp * e + s_.ki * integral_ + s_.kd * de;
    // Asked to stand still and already (almost) there: hold the brake, as the expert does.
    if (target_speed <= s_.stop_speed && speed <= s_.stop_speed) {
      integral_ = 0;
      return Control{0.0, s_.hold_brake};
    }
    return model_.control_for(a, speed);
  }

 private:
  ControlSettings s_;
  EgoModel model_;
  double dt_;
  double integral_ = 0, prev_error_ = 0;
  bool first_ = true;
};

}  // namespace cd
