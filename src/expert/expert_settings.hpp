#pragma once
// The expert's own tuning ([expert]): how it drives, never what the benchmark measures (the
// ground truth's margins are [world] settings, world/world_settings.hpp).

namespace cd {

struct ExpertSettings {
  double cruise_speed = 10.0;   // m/s, never above the lane's limit
  double turn_speed = 5.0;      // m/s through turns
  double comfort_decel = 3.0;   // m/s^2, planned braking
  double min_gap = 3.5;         // m, standstill gap to the leader
  double headway = 1.2;         // s
  double stop_margin = 1.0;     // m before a stop line
  double gain = 2.0;            // 1/s, speed tracking gain
};

}  // namespace cd
