#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <memory>
#include <vector>

#include "cli/commands.hpp"
#include "cli/common.hpp"
#include "core/error.hpp"
#include "collect/expert_episode.hpp"
#include "core/png.hpp"
#include "expert/autopilot.hpp"
#include "sense/bev_colour.hpp"
#include "world/town.hpp"
#include "world/world.hpp"

namespace cd::cli {

namespace {

// The places a preview shows: up to six driving lanes spread over the network, at the midpoint
// of each one's middle segment, heading along it.
std::vector<Pose2> preview_places(const World& world) {
  std::vector<const LaneGeom*> lanes;
  for (const LaneGeom& g : world.map().lanes)
    if (g.kind == LaneKind::Driving && !g.internal && g.length > 10) lanes.push_back(&g);
  if (lanes.empty()) throw SimError(world.network_path() + ": no driving lane to preview");
  const int tiles = std::min<int>(6, static_cast<int>(lanes.size()));
  std::vector<Pose2> places;
  for (int t = 0; t < tiles; ++t) {
    const LaneGeom& g = *lanes[static_cast<size_t>(t) * lanes.size() / tiles];
    const size_t i = g.shape.size() / 2;
    const Vec2 a = g.shape[i - 1], b = g.shape[i];
    places.push_back({(a + b) * 0.5, std::atan2(b.y - a.y, b.x - a.x)});
  }
  return places;
}

// BEV frames at the preview's places, tiled into one picture.
void write_preview(const Settings& settings, const std::string& png) {
  World world(settings);
  const std::vector<Pose2> places = preview_places(world);
  const int tiles = static_cast<int>(places.size());
  const int cols = std::min(3, tiles), rows = (tiles + cols - 1) / cols;
  const BevConfig& bc = world.renderer().config();
  const int C = kBevChannelCount, H = bc.height, W = bc.width;
  std::vector<uint8_t> frame(world.renderer().frame_bytes());
  std::vector<uint8_t> grid(static_cast<size_t>(C) * rows * H * cols * W, 0);
  for (int t = 0; t < tiles; ++t) {
    BevScene scene;
    scene.ego = places[static_cast<size_t>(t)];
    world.renderer().render(scene, frame.data());
    int r0 = (t / cols) * H, c0 = (t % cols) * W;
    for (int c = 0; c < C; ++c)
      for (int y = 0; y < H; ++y)
        std::memcpy(&grid[(static_cast<size_t>(c) * rows * H + r0 + y) * cols * W + c0],
                    &frame[(static_cast<size_t>(c) * H + y) * W], W);
  }
  write_bev_png(png, grid.data(), C, rows * H, cols * W);
  std::printf("preview of %d places -> %s\n", tiles, png.c_str());
}

// The front camera ([sense.camera]) at the same places as the BEV preview, stacked into one
// picture: the town's roads and its signal heads (all red), no traffic.
void write_camera_preview(const Settings& settings, const std::string& png) {
  World world(settings);
  const std::vector<Pose2> places = preview_places(world);
  const int tiles = static_cast<int>(places.size());
  CameraRenderer camera(world.map(), settings.camera);
  const int H = settings.camera.height, W = settings.camera.width;
  std::vector<uint8_t> frame(camera.frame_bytes()), rgb;
  CameraScene scene;
  for (const SignalHead& h : find_signal_heads(world.network()))
    scene.lights.push_back({h.pole, h.facing, 'r'});
  for (int t = 0; t < tiles; ++t) {
    scene.ego = places[static_cast<size_t>(t)];
    camera.render(scene, frame.data());
    append_rgb_rows(frame.data(), H, W, rgb);  // tile t below tile t-1
  }
  write_png_rgb(png, rgb, W, H * tiles);
  std::printf("camera preview of %d places -> %s\n", tiles, png.c_str());
}

// Copies a w x h RGB image (interleaved rows) into a canvas of width cw at (x0, y0), each pixel
// drawn as a scale x scale square.
void blit(std::vector<uint8_t>& canvas, int cw, const std::vector<uint8_t>& img, int w, int h,
          int x0, int y0, int scale = 1) {
  for (int y = 0; y < h * scale; ++y)
    for (int x = 0; x < w * scale; ++x)
      for (int c = 0; c < 3; ++c)
        canvas[(size_t(y0 + y) * cw + x0 + x) * 3 + c] =
            img[(size_t(y / scale) * w + x / scale) * 3 + c];
}

// One moment of the live world (the expert driving collect's task of `seed` in the config's
// traffic, `steps` steps in): the BEV (2x) beside the front camera in each of `weathers`,
// stacked, in one PNG.
void write_moment_preview(const Settings& settings, const std::string& png, uint64_t seed,
                          int steps, const std::vector<std::string>& weathers) {
  if (weathers.empty()) throw ConfigError("town --weathers: name at least one weather");
  World world(settings);
  std::vector<std::unique_ptr<CameraRenderer>> cameras;
  for (const std::string& w : weathers) {
    CameraConfig c = settings.camera;
    c.weather = w;
    check_camera_config(c);
    cameras.push_back(std::make_unique<CameraRenderer>(world.map(), c));
  }
  world.reset(collect_task(world, settings.collect, episode_seed(settings.collect.seed, int(seed))));
  const Autopilot expert(settings.expert);
  StepResult r;
  for (int i = 0; i < steps && r.outcome == Outcome::Running; ++i) r = world.step(expert.act(world));
  const BevConfig& bc = world.renderer().config();
  std::vector<uint8_t> bev(world.renderer().frame_bytes());
  world.renderer().render(world.scene(), bev.data());
  const std::vector<uint8_t> bev_rgb =
      frame_picture(bev.data(), kBevChannelCount, bc.height, bc.width, false);
  const int gap = 4, CW = settings.camera.width, CH = settings.camera.height;
  const int n = static_cast<int>(weathers.size());
  const int width = 2 * bc.width + gap + CW;
  const int height = std::max(2 * bc.height, n * CH + (n - 1) * gap);
  std::vector<uint8_t> canvas(size_t(width) * height * 3, 255);
  blit(canvas, width, bev_rgb, bc.width, bc.height, 0, 0, 2);
  std::vector<uint8_t> frame(cameras.front()->frame_bytes());
  const CameraScene scene = world.camera_scene();
  for (int k = 0; k < n; ++k) {
    cameras[static_cast<size_t>(k)]->render(scene, frame.data());
    blit(canvas, width, frame_picture(frame.data(), 3, CH, CW, true), CW, CH, 2 * bc.width + gap,
         k * (CH + gap));
  }
  write_png_rgb(png, canvas, width, height);
  std::printf("%s at %.1f s of episode seed %llu: BEV beside the camera in %d weather(s) -> %s\n",
              network_label(settings.world.town).c_str(), world.time(),
              static_cast<unsigned long long>(seed), n, png.c_str());
}

}  // namespace

void add_town(CLI::App& app) {
  auto names = std::make_shared<std::vector<std::string>>();
  auto net = std::make_shared<std::string>();
  auto preview = std::make_shared<std::string>();
  auto config = std::make_shared<std::string>();
  auto list = std::make_shared<bool>(false);
  CLI::App* sub = app.add_subcommand(
      "town", "generate the built-in towns (cached), or check a user network and preview it");
  sub->add_option("names", *names, "towns to generate (default: all)");
  sub->add_option("--net", *net, "a SUMO .net.xml to load instead of a built-in town");
  sub->add_option("--preview", *preview, "write a PNG of the BEV at a few places of the network");
  auto camera_preview = std::make_shared<std::string>();
  sub->add_option("--camera-preview", *camera_preview,
                  "write a PNG of the front camera ([sense.camera]) at the same places");
  auto moment = std::make_shared<std::string>();
  sub->add_option("--moment-preview", *moment,
                  "write a PNG of one moment of the live world (the expert driving a collect "
                  "task): its BEV beside the front camera in each of --weathers");
  auto weathers = std::make_shared<std::vector<std::string>>(
      std::vector<std::string>{"clear-noon", "soft-rain-sunset"});
  sub->add_option("--weathers", *weathers, "--moment-preview's weathers (default: clear-noon "
                  "soft-rain-sunset)");
  auto seed = std::make_shared<uint64_t>(0);
  sub->add_option("--episode", *seed, "--moment-preview's collect episode (default 0)");
  auto steps = std::make_shared<int>(150);
  sub->add_option("--steps", *steps, "--moment-preview's steps into the episode (default 150)")
      ->check(CLI::NonNegativeNumber);
  sub->add_option("--config,-c", *config, "TOML config for the BEV settings");
  sub->add_flag("--list", *list, "list the built-in towns");
  sub->callback([=] {
    if (*list) {
      for (const auto& n : town_names())
        std::printf("%-8s %s\n", n.c_str(), town_spec(n).description.c_str());
      return;
    }
    Settings s = settings_from(*config);
    std::vector<std::string> targets = *names;
    if (!net->empty()) {
      if (!targets.empty()) throw ConfigError("town: give either town names or --net, not both");
      targets = {*net};
    } else if (targets.empty()) {
      targets = town_names();
    }
    for (const auto& t : targets) {
      std::string path = resolve_network(t);
      std::printf("%-8s %s\n", network_label(t).c_str(), path.c_str());
    }
    if (!preview->empty()) {
      if (targets.size() != 1)
        throw ConfigError("town --preview needs exactly one town name or --net FILE");
      s.world.town = targets.front();
      write_preview(s, *preview);
    }
    if (!camera_preview->empty()) {
      if (targets.size() != 1)
        throw ConfigError("town --camera-preview needs exactly one town name or --net FILE");
      s.world.town = targets.front();
      write_camera_preview(s, *camera_preview);
    }
    if (!moment->empty()) {
      if (targets.size() != 1)
        throw ConfigError("town --moment-preview needs exactly one town name or --net FILE");
      s.world.town = targets.front();
      write_moment_preview(s, *moment, *seed, *steps, *weathers);
    }
  });
}

}  // namespace cd::cli
