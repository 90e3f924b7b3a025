#pragma once
// The front camera (SPEC section 16): a perspective RGB image from the ego's windscreen,
// rendered headless from the world's state (render/gl_context), beside the bird's-eye view.
//
// Pixel convention (the tests compute it by hand): the output is 3 x H x W uint8, RGB planes,
// top row first. The camera sits `mount_forward` m ahead of the ego's centre, `mount_height` m
// above the ground, looks along the ego's heading tilted down by `pitch_deg`, with a horizontal
// field of view `hfov_deg` and square pixels. A point whose camera coordinates are (right, up,
// depth) lands at continuous pixel coordinates
//     col = W/2 + f * right / depth,   row = H/2 - f * up / depth,   f = (W/2) / tan(hfov/2),
// pixel (r, c) covering rows [r, r+1) and columns [c, c+1): camera_project() computes it, and
// the GL projection is built from the same numbers.
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "core/geometry.hpp"
#include "world/road_map.hpp"

namespace cd {

class GlContext;

// A named appearance set (SPEC 16 "weathers"): colours as linear RGB in [0, 1].
struct CameraWeather {
  std::string name;
  bool held_out = false;  // not used for training: table 8's "new weather" for the camera
  float sky[3], ground[3], road[3], sidewalk[3], marking[3], kerb[3];
  double sun_azimuth_deg = 0;    // compass-free: 0 = east, counter-clockwise
  double sun_elevation_deg = 45;
  double ambient = 0.45;         // share of a face's colour lit without the sun
  double fog_density = 0;        // exponential fog per metre (0: none)
};

// The named sets: four to train on (clear-noon, wet-noon, hard-rain-noon, clear-sunset) and two
// held out (soft-rain-sunset, after-rain-dusk).
const std::vector<CameraWeather>& camera_weathers();
// Throws ConfigError naming the known sets.
const CameraWeather& camera_weather(const std::string& name);
// The set of that name, or nullptr (a pool's name is no set).
const CameraWeather* find_camera_weather(const std::string& name);
std::vector<std::string> camera_weather_names();
// `sense.camera.weather` names one set, or a pool that each episode draws one set from: "train"
// (the four training sets) or "held-out" (the two held out: table 8's new weather).
inline constexpr const char* kTrainWeathers = "train";
inline constexpr const char* kHeldOutWeathers = "held-out";
// What `sense.camera.weather` accepts: the pools, then every set's name.
std::vector<std::string> camera_weather_settings();
// The set an episode renders: the setting itself when it names a set, otherwise the pool's set
// drawn by the episode's seed (the task's traffic seed), so a seed always gets the same one.
// Throws ConfigError for an unknown setting.
const CameraWeather& episode_weather(const std::string& setting, uint64_t seed);
// The camera's frame channels, as recorded and as MuJoCo-Image's RGB frames name them.
const std::vector<std::string>& camera_channel_names();

struct CameraConfig {
  int width = 288;   // seed 001's 288 x 80; CILRS's crop is 200 x 88
  int height = 80;
  double mount_height = 1.4;   // m above the ground
  double mount_forward = 0.8;  // m ahead of the ego's centre
  double pitch_deg = 0.0;      // down positive
  double hfov_deg = 90.0;
  double near_m = 0.3, far_m = 600.0;
  std::string weather = kTrainWeathers;  // a set, or a pool drawn per episode (above)
};
// Throws ConfigError naming the setting out of range.
void check_camera_config(const CameraConfig& c);

struct Vec3 {
  double x = 0, y = 0, z = 0;
};
inline double dot(Vec3 a, Vec3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }

// The camera of an ego at a pose: its position and axes in the network frame (z up), and the
// intrinsics of the pixel convention above. The GL view and projection are built from it.
struct CameraFrame {
  Vec3 position, forward, right, up;
  double focal = 0, cx = 0, cy = 0;
};
CameraFrame camera_frame(const CameraConfig& c, const Pose2& ego);

// Continuous pixel coordinates of a point.
struct PixelPoint {
  double row = 0, col = 0, depth = 0;
};
// Where the network-frame point (p, z metres up) lands for a camera on an ego at `ego`; nullopt
// when it lies behind the near plane.
std::optional<PixelPoint> camera_project(const CameraConfig& c, const Pose2& ego, Vec2 p, double z);

// The dynamic content of one frame.
struct CameraScene {
  Pose2 ego;
  struct Vehicle {
    Box box;
    double height = 1.5;
    uint32_t colour = 0x808080;  // 0xRRGGBB
    bool braking = false;        // brake lights lit
  };
  std::vector<Vehicle> vehicles;
  struct Pedestrian {
    Box box;
    double height = 1.75;
    uint32_t colour = 0x3050a0;
  };
  std::vector<Pedestrian> pedestrians;
  // A signal head on a pole at a controlled stop line, its lamps facing `facing` (the direction
  // the lamps look: against the approaching traffic's heading).
  struct Light {
    Vec2 position;      // the pole's foot
    double facing = 0;  // radians, as Pose2::heading
    char state = 'r';   // 'r' red, 'y' yellow, 'g' green (green with or without priority)
  };
  std::vector<Light> lights;
};

// The geometry of the signal head (metres), shared by the renderer and the tests.
struct LightHeadGeometry {
  double pole_height = 3.2;   // the head's bottom
  double head_height = 1.0, head_width = 0.36, head_depth = 0.3;
  double lamp_size = 0.24;    // square lamps on the front face
  // Height above the ground of lamp k's centre: 0 red (top), 1 yellow, 2 green (bottom).
  double lamp_centre_height(int k) const { return pole_height + head_height * (5 - 2 * k) / 6.0; }
};
inline constexpr LightHeadGeometry kLightHead{};

class CameraRenderer {
 public:
  // Builds the town's flat layers (ground, roads, sidewalks, markings, kerbs) once, as a raster
  // of 5 cm texels (sense/camera_renderer.cpp).
  // Throws ConfigError for a bad config, SimError when no GL context can be made.
  CameraRenderer(const RoadMap& map, CameraConfig cfg);
  ~CameraRenderer();
  CameraRenderer(const CameraRenderer&) = delete;
  CameraRenderer& operator=(const CameraRenderer&) = delete;

  // Writes 3 * height * width bytes (RGB planes, top row first) to out.
  void render(const CameraScene& scene, uint8_t* out);
  // The appearance set rendered from now on (the next frame recomputes the flat layers'
  // colours for it, ~1 ms). The constructor starts with episode_weather(config's weather, 0).
  void set_weather(const CameraWeather& weather);
  const CameraWeather& weather() const { return *weather_; }

  const CameraConfig& config() const { return cfg_; }
  size_t frame_bytes() const { return size_t(3) * cfg_.width * cfg_.height; }

 private:
  CameraConfig cfg_;
  const CameraWeather* weather_;
  std::unique_ptr<GlContext> gl_;
  // The town's flat layers and the per-pixel rays onto the ground (sense/camera_renderer.cpp).
  struct Ground;
  std::unique_ptr<Ground> ground_;
};

}  // namespace cd
