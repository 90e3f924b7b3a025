#pragma once
// The ego's vehicle model: throttle and brake in [0,1] -> acceleration with limits
// (longitudinal), and, with ego.lateral = "free", steer in [-1,1] -> a road-wheel angle with a
// rate limit driving a kinematic bicycle (lateral).
#include <algorithm>
#include <cmath>

#include "core/geometry.hpp"

#include "world/world_settings.hpp"

namespace cd {

struct Control {
  double throttle = 0;  // [0,1]
  double brake = 0;     // [0,1]
  double steer = 0;     // [-1,1], positive to the left; ignored with ego.lateral = "route"
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

  // The road-wheel angle after one step: towards steer * max_steer, at most steer_rate * dt
  // away from `angle` (rad, positive to the left).
  double next_steer_angle(double angle, double steer, double dt) const {
    const double target = std::clamp(steer, -1.0, 1.0) * s_.max_steer;
    const double step = s_.steer_rate * dt;
    return angle + std::clamp(target - angle, -step, step);
  }

  // The pose of the box centre after one step of a kinematic bicycle whose centre lies midway
  // between the axles: slip angle beta = atan(tan(angle) / 2), yaw rate v sin(beta) / (L / 2).
  // The step is an exact circular arc at the mean of the speeds before and after it.
  Pose2 next_pose(const Pose2& p, double v0, double v1, double angle, double dt) const {
    const double v = 0.5 * (v0 + v1);
    const double beta = std::atan(0.5 * std::tan(angle));
    const double yaw_rate = v * std::sin(beta) / (0.5 * s_.wheelbase);
    const double h0 = p.heading + beta, dh = yaw_rate * dt;
    Pose2 out;
    out.heading = p.heading + dh;
    if (std::abs(dh) < 1e-9) {
      out.pos = {p.pos.x + v * dt * std::cos(h0), p.pos.y + v * dt * std::sin(h0)};
    } else {
      const double r = v / yaw_rate;  // radius of the centre's arc
      out.pos = {p.pos.x + r * (std::sin(h0 + dh) - std::sin(h0)),
                 p.pos.y - r * (std::cos(h0 + dh) - std::cos(h0))};
    }
    return out;
  }

  const EgoSettings& settings() const { return s_; }

 private:
  EgoSettings s_;
};

}  // namespace cd
