#pragma once
// Longitudinal model of the ego: throttle and brake in [0,1] -> acceleration with limits.
#include <algorithm>

#include "world/world_settings.hpp"

namespace cd {

struct Control {
  double throttle = 0;  // [0,1]
  double brake = 0;     // [0,1]
};

class EgoModel {
 public:
  explicit EgoModel(const EgoSettings& s) : s_(s) {}

  // Acceleration produced by a control at speed v (before the speed clamp).
  double acceleration(const Control& c, double v) const {
    double t = std::clamp(c.throttle, 0.0, 1.0), b = std::clamp(c.brake, 0.0, 1.0);
    double resist = v > 0 ? s_.rolling + s_.drag * v * v : 0.0;
    return t * s_.max_accel * std::max(0.0, 1.0 - v / s_.max_speed) - b * s_.max_decel - resist;
  }

  // Speed after one step of dt; never negative (no reverse), never above max_speed.
  double next_speed(const Control& c, double v, double dt) const {
    return std::clamp(v + acceleration(c, v) * dt, 0.0, s_.max_speed);
  }

  // The control that produces acceleration `a` at speed v, as closely as the limits allow.
  Control control_for(double a, double v) const {
    double resist = v > 0 ? s_.rolling + s_.drag * v * v : 0.0;
    double need = a + resist;
    Control c;
    double full = s_.max_accel * std::max(0.0, 1.0 - v / s_.max_speed);
    if (need > 0) {
      c.throttle = full > 1e-9 ? std::min(1.0, need / full) : 1.0;
    } else {
      c.brake = std::min(1.0, -need / s_.max_decel);
    }
    return c;
  }

  const EgoSettings& settings() const { return s_; }

 private:
  EgoSettings s_;
};

}  // namespace cd
