#include "sense/sensor_shift.hpp"

#include <cmath>

#include "core/error.hpp"
#include "core/rng.hpp"

namespace cd {

namespace {

constexpr uint64_t kFadeStream = 0xfade;  // sub-stream of the seed for the worn paint

// N(0, 1) by Box-Muller from two draws (no std:: distribution: same bytes everywhere).
double gaussian(Rng& rng) {
  const double u1 = 1.0 - rng.uniform();  // (0, 1]
  const double u2 = rng.uniform();
  return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * M_PI * u2);
}

// Poisson(mean) by multiplying uniforms (Knuth); means are small (at most a few per frame).
int poisson(Rng& rng, double mean) {
  if (!(mean > 0)) return 0;
  const double limit = std::exp(-mean);
  int k = 0;
  for (double p = rng.uniform(); p > limit; p *= rng.uniform()) ++k;
  return k;
}

// Missed, or moved and turned: the draws of one box in a fixed order.
bool perceive(Box& box, const SensorShift& s, Rng& rng) {
  if (rng.uniform() < s.miss) return false;
  if (s.jitter_m > 0) {
    box.center.x += s.jitter_m * gaussian(rng);
    box.center.y += s.jitter_m * gaussian(rng);
    box.heading += s.jitter_m * kHeadingJitterPerM * gaussian(rng);
  }
  return true;
}

}  // namespace

uint64_t sensor_frame_key(uint64_t seed, uint64_t episode_key, uint64_t frame) {
  return derive_seed(derive_seed(seed, episode_key), frame);
}

BevScene shift_scene(const BevScene& scene, const SensorShift& s, const BevConfig& cfg,
                     uint64_t frame_key) {
  Rng rng(frame_key);
  BevScene out;
  out.ego = scene.ego;
  out.stop_lines = scene.stop_lines;
  for (Box b : scene.vehicles)
    if (perceive(b, s, rng)) out.vehicles.push_back(b);
  for (Box b : scene.pedestrians)
    if (perceive(b, s, rng)) out.pedestrians.push_back(b);

  // Ghosts anywhere in the view: forward in [-(H - row_e), row_e] pixels, left in [-W/2, W/2].
  const double mpp = cfg.metres_per_pixel;
  const double row_e = cfg.height * cfg.ego_row_fraction, half_w = cfg.width / 2.0;
  const Vec2 fwd{std::cos(scene.ego.heading), std::sin(scene.ego.heading)};
  const Vec2 left{-fwd.y, fwd.x};
  const int n = poisson(rng, s.ghosts);
  for (int i = 0; i < n; ++i) {
    const double f = rng.uniform(row_e - cfg.height, row_e) * mpp;
    const double l = rng.uniform(-half_w, half_w) * mpp;
    const double heading = rng.uniform(-M_PI, M_PI);
    const bool pedestrian = rng.uniform() < kGhostPedestrianShare;
    Box g{scene.ego.pos + fwd * f + left * l, heading, pedestrian ? kGhostPedSize : kGhostCarLength,
          pedestrian ? kGhostPedSize : kGhostCarWidth};
    (pedestrian ? out.pedestrians : out.vehicles).push_back(g);
  }
  return out;
}

void fade_markings(uint8_t* frame, const BevConfig& cfg, const Pose2& ego, const SensorShift& s) {
  if (!(s.fade > 0)) return;
  const int H = cfg.height, W = cfg.width;
  const double mpp = cfg.metres_per_pixel;
  const double row_e = H * cfg.ego_row_fraction, col_e = W / 2.0;
  const Vec2 fwd{std::cos(ego.heading), std::sin(ego.heading)};
  const Vec2 left{-fwd.y, fwd.x};
  const uint64_t stream = derive_seed(s.seed, kFadeStream);
  uint8_t* plane = frame + size_t(kBevMarkings) * H * W;
  for (int r = 0; r < H; ++r)
    for (int c = 0; c < W; ++c) {
      uint8_t& px = plane[size_t(r) * W + c];
      if (!px) continue;
      const Vec2 p = ego.pos + fwd * ((row_e - (r + 0.5)) * mpp) + left * ((col_e - (c + 0.5)) * mpp);
      const auto cx = static_cast<int64_t>(std::floor(p.x / kFadeCell));
      const auto cy = static_cast<int64_t>(std::floor(p.y / kFadeCell));
      const uint64_t h = derive_seed(derive_seed(stream, static_cast<uint64_t>(cx)),
                                     static_cast<uint64_t>(cy));
      if (static_cast<double>(h >> 11) * 0x1.0p-53 < s.fade) px = 0;
    }
}

void render_sensor(const BevRenderer& renderer, const BevScene& scene, const SensorShift* shift,
                   uint64_t frame_key, uint8_t* out) {
  if (!shift) {
    renderer.render(scene, out);
    return;
  }
  renderer.render(shift_scene(scene, *shift, renderer.config(), frame_key), out);
  fade_markings(out, renderer.config(), scene.ego, *shift);
}

void require_bev_for_shift(const std::string& view) {
  if (view != "bev")
    throw ConfigError("eval.sensor = \"shifted\" is the BEV's perception noise; the camera's "
                      "new sensor condition is a held-out weather (sense.camera.weather)");
}

}  // namespace cd
