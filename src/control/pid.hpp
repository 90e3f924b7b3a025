#pragma once
// Speed controller shared by every agent that outputs a target speed (cs, the target-speed
// head of bc-so/bc-oh, CIM): PID on the speed error gives an acceleration command, and the
// ego's vehicle model turns it into throttle if positive, brake otherwise (seed 000, eq. 2).
#include <algorithm>

#include "world/ego_model.hpp"

namespace cd {

// Speed controller of every agent with a target-speed output (control/pid.hpp).
struct ControlSettings {
  double kp = 4.0;              // 1/s: m/s^2 asked per m/s of speed error
  double ki = 0.5;              // 1/s^2
  double kd = 0.0;              // dimensionless
  double integral_limit = 2.0;  // m, anti-windup bound of the integrated error
  double stop_speed = 0.1;      // m/s: a target and a speed both below it mean "hold still"
  double hold_brake = 0.3;      // brake held while standing
};


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
