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

double Autopilot::target_speed(const World& w) const {
  const GroundTruth& gt = w.truth();
  const EgoState& ego = w.ego();
  const double b = s_.comfort_decel;
  double v = std::min(s_.cruise_speed, ego.lane_speed_limit);

  bool turning = w.command() == kLeft || w.command() == kRight;
  if (turning) v = std::min(v, std::hypot(s_.turn_speed, stop_profile(gt.junction_distance, b)));

  if (gt.lead_present) {
    // Krauss-style safe speed: able to stop behind the leader even if it brakes at b.
    double gap = gt.lead_distance - s_.min_gap;
    double vl = std::max(0.0, gt.lead_speed);
    double bt = b * s_.headway;
    double safe = -bt + std::sqrt(bt * bt + vl * vl + 2.0 * b * std::max(0.0, gap));
    v = std::min(v, gap <= 0 ? 0.0 : safe);
  }

  double stop_at = gt.tl_distance - s_.stop_margin;
  if (gt.tl_state == kTlRed) v = std::min(v, stop_profile(stop_at, b));
  if (gt.tl_state == kTlYellow) {
    // Stop for yellow only when that is possible without hard braking.
    bool can_stop = ego.speed * ego.speed / (2.0 * 1.5 * b) <= std::max(0.0, stop_at);
    if (can_stop) v = std::min(v, stop_profile(stop_at, b));
  }
  if (gt.must_yield && gt.junction_distance > 0)
    v = std::min(v, stop_profile(gt.junction_distance - s_.stop_margin, b));
  if (gt.ped_on_path) v = std::min(v, stop_profile(gt.ped_distance - s_.min_gap, b));
  return std::max(0.0, v);
}

Control Autopilot::act(const World& w) const {
  double target = target_speed(w);
  double v = w.ego().speed;
  const EgoModel& model = w.ego_model();
  double a = s_.gain * (target - v);
  // Whatever brake is needed to stop in time, even above the comfortable rate.
  a = std::clamp(a, -model.settings().max_decel, model.settings().max_accel);
  Control c = model.control_for(a, v);
  if (target < 0.05 && v < 0.3) c = {0.0, std::max(c.brake, 0.3)};  // hold while stopped
  return c;
}

}  // namespace cd
