#include "expert/autopilot.hpp"

#include <algorithm>
#include <cmath>

namespace cd {

namespace {

// Highest speed from which braking at `decel` stops within `distance`.
double stop_profile(double distance, double decel) {
  return std::sqrt(2.0 * decel * std::max(0.0, distance));
}

}  // namespace

Autopilot::Plan Autopilot::plan(const World& w) const {
  const GroundTruth& gt = w.truth();
  const EgoState& ego = w.ego();
  const double b = s_.comfort_decel;
  Plan p;
  p.speed = std::min(s_.cruise_speed, ego.lane_speed_limit);
  auto stop_at = [&](double distance) { p.stop = std::min(p.stop, distance); };

  bool turning = w.command() == kLeft || w.command() == kRight;
  if (turning)
    p.speed = std::min(p.speed, std::hypot(s_.turn_speed, stop_profile(gt.junction_distance, b)));

  if (gt.lead_present) {
    // Krauss-style safe speed: able to stop behind the leader even if it brakes at b.
    double gap = gt.lead_distance - s_.min_gap;
    double vl = std::max(0.0, gt.lead_speed);
    double bt = b * s_.headway;
    double safe = -bt + std::sqrt(bt * bt + vl * vl + 2.0 * b * std::max(0.0, gap));
    p.speed = std::min(p.speed, gap <= 0 ? 0.0 : safe);
    if (vl < 0.5) stop_at(gap);
  }

  double line = gt.tl_distance - s_.stop_margin;
  if (gt.tl_state == kTlRed) stop_at(line);
  if (gt.tl_state == kTlYellow) {
    // Stop for yellow only when that is possible without hard braking.
    if (ego.speed * ego.speed / (2.0 * 1.5 * b) <= std::max(0.0, line)) stop_at(line);
  }
  if (gt.must_yield) stop_at(gt.yield_distance - s_.stop_margin);
  // Keep the junction clear: enter only when there is room behind a slow leader beyond it.
  bool before_junction = gt.junction_distance > 0 && gt.junction_exit_distance > 0;
  if (before_junction && gt.lead_present && gt.lead_speed < 2.0 &&
      gt.lead_distance < gt.junction_exit_distance + w.settings().ego.length + s_.min_gap)
    stop_at(gt.junction_distance - s_.stop_margin);
  if (gt.ped_on_path) stop_at(gt.ped_distance - s_.min_gap);
  // A lane change the route needs, held back by traffic on the lane it joins: wait where it
  // must begin at the latest.
  if (w.lane_change_hold() < 1e8) stop_at(w.lane_change_hold());

  p.speed = std::max(0.0, std::min(p.speed, stop_profile(p.stop, b)));
  return p;
}

double Autopilot::target_speed(const World& w) const { return plan(w).speed; }

Control Autopilot::act(const World& w) const {
  Plan p = plan(w);
  double v = w.ego().speed;
  const EgoModel& model = w.ego_model();
  double a = s_.gain * (p.speed - v);
  // Near a stop the speed profile alone lags: brake exactly as hard as the distance needs.
  if (p.stop < 1e8 && v > 0.05) {
    double needed = -v * v / (2.0 * std::max(p.stop, 0.05));
    if (needed < -0.3 * s_.comfort_decel) a = std::min(a, needed);
  }
  a = std::clamp(a, -model.settings().max_decel, model.settings().max_accel);
  Control c = model.control_for(a, v);
  if (p.speed < 0.05 && v < 0.3) c = {0.0, std::max(c.brake, 0.3)};  // hold while stopped
  if (w.free_lateral()) c.steer = steer_towards_path(w);
  return c;
}

double pursuit_steer(const Pose2& pose, Vec2 target, const EgoSettings& e) {
  const Vec2 t = to_ego_frame(pose, target);
  const double x = t.x + 0.5 * e.wheelbase, y = t.y;  // from the rear axle
  const double d2 = x * x + y * y;
  if (d2 < 1e-6) return 0.0;
  const double angle = std::atan(2.0 * e.wheelbase * y / d2);  // 2 L sin(alpha) / d
  return std::clamp(angle / e.max_steer, -1.0, 1.0);
}

double steer_towards_path(const World& w) { return steer_towards_path(w, w.ego().pose); }

double steer_towards_path(const World& w, const Pose2& pose) {
  // The point of the route path a speed-dependent distance ahead of the front bumper.
  const double ahead = std::clamp(1.0 + 0.3 * w.ego().speed, 1.5, 8.0);
  return pursuit_steer(pose, w.path_point(ahead), w.ego_model().settings());
}

}  // namespace cd
