#include "sense/camera.hpp"
#include "sense/camera_projection.hpp"

#include <cmath>

#include "core/error.hpp"
#include "core/rng.hpp"

namespace cd {

const std::vector<CameraWeather>& camera_weathers() {
  // name, held out, sky, ground, road, sidewalk, marking, kerb, sun azimuth, elevation,
  // ambient, fog density.
  static const std::vector<CameraWeather> weathers = {
      {"clear-noon", false, {0.53f, 0.72f, 0.92f}, {0.36f, 0.48f, 0.25f}, {0.33f, 0.33f, 0.35f},
       {0.62f, 0.60f, 0.57f}, {0.92f, 0.92f, 0.90f}, {0.75f, 0.74f, 0.72f}, 30, 60, 0.45, 0.0},
      {"wet-noon", false, {0.60f, 0.66f, 0.72f}, {0.30f, 0.40f, 0.22f}, {0.22f, 0.23f, 0.25f},
       {0.48f, 0.47f, 0.46f}, {0.80f, 0.80f, 0.80f}, {0.60f, 0.60f, 0.58f}, 30, 60, 0.55, 0.002},
      {"hard-rain-noon", false, {0.45f, 0.47f, 0.50f}, {0.25f, 0.31f, 0.20f},
       {0.20f, 0.20f, 0.22f}, {0.40f, 0.40f, 0.40f}, {0.70f, 0.70f, 0.70f}, {0.52f, 0.52f, 0.50f},
       30, 60, 0.70, 0.012},
      {"clear-sunset", false, {0.95f, 0.62f, 0.38f}, {0.38f, 0.36f, 0.20f}, {0.36f, 0.31f, 0.30f},
       {0.62f, 0.52f, 0.45f}, {0.95f, 0.85f, 0.72f}, {0.75f, 0.65f, 0.55f}, 200, 8, 0.35, 0.0},
      {"soft-rain-sunset", true, {0.70f, 0.52f, 0.45f}, {0.30f, 0.30f, 0.20f},
       {0.24f, 0.21f, 0.22f}, {0.50f, 0.44f, 0.40f}, {0.82f, 0.74f, 0.66f}, {0.60f, 0.54f, 0.50f},
       200, 10, 0.55, 0.006},
      {"after-rain-dusk", true, {0.30f, 0.32f, 0.45f}, {0.18f, 0.22f, 0.16f},
       {0.17f, 0.17f, 0.20f}, {0.36f, 0.36f, 0.40f}, {0.66f, 0.66f, 0.70f}, {0.45f, 0.45f, 0.50f},
       250, 3, 0.60, 0.004},
  };
  return weathers;
}

std::vector<std::string> camera_weather_names() {
  std::vector<std::string> names;
  for (const CameraWeather& w : camera_weathers()) names.push_back(w.name);
  return names;
}

const std::vector<std::string>& camera_channel_names() {
  static const std::vector<std::string> names = {"red", "green", "blue"};
  return names;
}

std::vector<std::string> camera_weather_settings() {
  std::vector<std::string> out = {kTrainWeathers, kHeldOutWeathers};
  for (const std::string& n : camera_weather_names()) out.push_back(n);
  return out;
}

const CameraWeather& episode_weather(const std::string& setting, uint64_t seed) {
  const bool train = setting == kTrainWeathers;
  if (!train && setting != kHeldOutWeathers) return camera_weather(setting);
  std::vector<const CameraWeather*> pool;
  for (const CameraWeather& w : camera_weathers())
    if (w.held_out != train) pool.push_back(&w);
  // Its own stream of the seed (derive_seed's index 7), apart from the traffic's.
  return *pool[derive_seed(seed, 7) % pool.size()];
}

const CameraWeather* find_camera_weather(const std::string& name) {
  for (const CameraWeather& w : camera_weathers())
    if (w.name == name) return &w;
  return nullptr;
}

const CameraWeather& camera_weather(const std::string& name) {
  if (const CameraWeather* w = find_camera_weather(name)) return *w;
  std::string known;
  for (const CameraWeather& w : camera_weathers()) known += (known.empty() ? "" : ", ") + w.name;
  throw ConfigError("sense.camera.weather: unknown weather '" + name + "' (known: " +
                    kTrainWeathers + ", " + kHeldOutWeathers + ", " + known + ")");
}

void check_camera_config(const CameraConfig& c) {
  auto bad = [](const std::string& what) { throw ConfigError("sense.camera." + what); };
  if (c.width < 8 || c.width > 4096 || c.height < 8 || c.height > 4096)
    bad("width and height must be 8 to 4096 pixels");
  if (!(c.hfov_deg >= 10 && c.hfov_deg <= 170)) bad("hfov_deg must be 10 to 170");
  if (!(c.pitch_deg >= -45 && c.pitch_deg <= 60)) bad("pitch_deg must be -45 to 60");
  if (!(c.mount_height > 0 && c.mount_height <= 10)) bad("mount_height must be in (0, 10] m");
  if (!(std::abs(c.mount_forward) <= 10)) bad("mount_forward must be within 10 m of the centre");
  if (!(c.near_m > 0 && c.far_m > 2 * c.near_m)) bad("near_m > 0 and far_m > 2 near_m");
  episode_weather(c.weather, 0);
}

CameraFrame camera_frame(const CameraConfig& c, const Pose2& ego) {
  const double h = ego.heading, t = c.pitch_deg * M_PI / 180.0;
  const double ch = std::cos(h), sh = std::sin(h), ct = std::cos(t), st = std::sin(t);
  CameraFrame f;
  f.position = {ego.pos.x + ch * c.mount_forward, ego.pos.y + sh * c.mount_forward, c.mount_height};
  f.forward = {ch * ct, sh * ct, -st};
  f.right = {sh, -ch, 0};
  f.up = {ch * st, sh * st, ct};
  f.focal = 0.5 * c.width / std::tan(0.5 * c.hfov_deg * M_PI / 180.0);
  f.cx = 0.5 * c.width;
  f.cy = 0.5 * c.height;
  return f;
}

std::optional<PixelPoint> camera_project(const CameraFrame& f, double near_m, Vec3 p) {
  const Vec3 d{p.x - f.position.x, p.y - f.position.y, p.z - f.position.z};
  const double depth = dot(d, f.forward);
  if (depth < near_m) return std::nullopt;
  return PixelPoint{f.cy - f.focal * dot(d, f.up) / depth,
                    f.cx + f.focal * dot(d, f.right) / depth, depth};
}

std::optional<PixelPoint> camera_project(const CameraConfig& c, const Pose2& ego, Vec2 p,
                                         double z) {
  return camera_project(camera_frame(c, ego), c.near_m, Vec3{p.x, p.y, z});
}

}  // namespace cd
