#pragma once
// The settings of the driving world and of the ego's vehicle model ([world], [ego]).
#include <string>

#include "sense/bev.hpp"
#include "sense/camera.hpp"

namespace cd {

struct TrafficDensity {
  double cars_per_km = 0;  // background cars per km of driving lane
  double peds_per_km = 0;  // pedestrians per km of driving lane
};

struct WorldSettings {
  std::string town = "town-a";  // a town name (towns/*.toml) or a path to a .net.xml
  std::string traffic = "regular";  // empty | regular | dense
  double dt = 0.1;                  // s per step
  double warmup_s = 60;             // background traffic runs this long before the ego enters
  TrafficDensity regular{4.0, 3.0};
  TrafficDensity dense{9.0, 8.0};
  double view_radius = 60;      // m, actors farther than this are not sensed or checked
  double command_horizon = 30;  // m, the junction command is given this far ahead
  // What the ground truth counts as in the ego's way (world/ground_truth.hpp). These define
  // "path free", hence inertia: they belong to the benchmark, never to the expert's tuning.
  double path_free_margin = 6;  // m checked beyond the stopping distance for "path free"
  double path_free_decel = 3.0; // m/s^2 of that stopping distance
  double vehicle_margin = 0.4;  // m beside the ego's body within which a car is in the way
  double ped_margin = 0.8;      // m beside the ego's body within which a pedestrian is
  double ped_lookahead_s = 1.5; // s, pedestrians are also checked where they will be
  // A pedestrian beside the ego's body (ped_margin) straight ahead of its front, as far as it
  // drives in ped_lookahead_s plus 1 m but at most ped_ahead_m, is in its way even off the route
  // path (a free ego's body leaves the path in turns: a pedestrian in front of it must not drop
  // out of the path test)
  double ped_ahead_m = 8.0;
  // A pedestrian standing still (under 0.1 m/s) off the route path is in that corridor only
  // within this much of the body's side: one waiting at the kerb beside a turn stands there
  // until the ego has passed (SUMO's walkers yield at unprioritised crossings), so the
  // ped_margin band would hold both for good (town-b-regular task 13 trial 2, ped31)
  double ped_standing_margin = 0.3;
  double yield_time = 5.0;      // s, priority traffic closer than this in time is waited for
};

// Longitudinal vehicle model of the ego: a = throttle * max_accel * (1 - v / max_speed)
// - brake * max_decel - rolling - drag * v^2, speed clamped to [0, max_speed].
struct EgoSettings {
  double length = 4.5;
  double width = 1.8;
  double max_accel = 3.5;   // m/s^2 at standstill, full throttle
  double max_decel = 8.0;   // m/s^2, full brake
  double max_speed = 20.0;  // m/s
  double rolling = 0.1;     // m/s^2, when moving
  double drag = 0.0008;     // 1/m
  // Lateral control (SPEC section 1, "Ego"): "free" (a kinematic bicycle driven by steer in
  // [-1, 1], placed in SUMO every step; the default) or "route" (SUMO keeps the ego on its
  // route's lanes; steer is ignored: the route-mode tables, methods that only learn speed).
  std::string lateral = "free";
  double wheelbase = 2.7;   // m
  double max_steer = 0.6;   // rad of road-wheel angle at steer = +-1
  double steer_rate = 1.0;  // rad/s the road wheels turn at most
};

// The density of world.traffic (none for "empty").
inline TrafficDensity traffic_density(const WorldSettings& w) {
  if (w.traffic == "regular") return w.regular;
  if (w.traffic == "dense") return w.dense;
  return {};
}

// What a World is built from: the [world], [ego], [bev], [sense] and [sense.camera] tables
// (app/settings.hpp's Settings holds them as its base).
struct WorldConfig {
  WorldSettings world;
  EgoSettings ego;
  BevConfig bev;
  CameraConfig camera;  // the front camera (sense/camera.hpp)
  // sense.view: what the ego's sensor gives agents and recordings, "bev" (the semantic
  // bird's-eye view of [bev]) or "camera" (the front camera of [sense.camera], RGB).
  std::string view = "bev";
};

// What the ego's sensor gives each step (sense.view): "bev" or "camera", C planes of H x W bytes
// with the channels' names (the BEV's layers; red, green, blue), and the BEV's scale (0 for
// the camera).
struct FrameFormat {
  std::string view = "bev";
  int channels = 0, height = 0, width = 0;
  std::vector<std::string> channel_names;
  double metres_per_pixel = 0;
  size_t pixels() const { return static_cast<size_t>(height) * width; }
  size_t bytes() const { return static_cast<size_t>(channels) * pixels(); }
};

// The frames a World of these settings gives (World::frame_format()).
inline FrameFormat frame_format_of(const WorldConfig& c) {
  if (c.view == "camera")
    return {"camera", 3, c.camera.height, c.camera.width, camera_channel_names(), 0.0};
  const auto& names = bev_channel_names();
  return {"bev", static_cast<int>(kBevChannelCount), c.bev.height, c.bev.width,
          {names.begin(), names.end()}, c.bev.metres_per_pixel};
}

}  // namespace cd
