// The shifted sensor (eval.sensor = "shifted"): seeded, deterministic perception noise on a
// hand-made road with cars and pedestrians. Same key, same bytes; another seed or frame,
// another frame; the clean sensor is the renderer's own frame; each kind of noise does what
// it says (misses, jitter, ghosts, worn paint) and leaves the route and the light alone.
#include "sense/sensor_shift.hpp"

#include <gtest/gtest.h>

#include <cstdint>
#include <string>
#include <vector>

namespace cd {
namespace {

LaneGeom lane(const std::string& id, Polyline shape) {
  LaneGeom l;
  l.id = id;
  l.edge = id.substr(0, id.rfind('_'));
  l.kind = LaneKind::Driving;
  l.width = 3.2;
  l.shape = std::move(shape);
  l.length = polyline_length(l.shape);
  return l;
}

// One road, one lane each way (E_0 eastbound on y = 0, W_0 westbound on y = 3.2), the ego on
// E_0 heading east, three cars and two pedestrians in view, a red stop line ahead.
struct Road {
  RoadMap map;
  BevScene scene;
  Road() {
    map.add(lane("E_0", {{-200, 0}, {200, 0}}));
    map.add(lane("W_0", {{200, 3.2}, {-200, 3.2}}));
    scene.ego = {{0, 0}, 0};
    scene.vehicles = {{{10, 0}, 0, 4.5, 1.8}, {{-8, 3.2}, M_PI, 4.5, 1.8}, {{18, 3.2}, M_PI, 4.5, 1.8}};
    scene.pedestrians = {{{6, 5.5}, 1.0, 0.5, 0.5}, {{12, -2.5}, 2.0, 0.5, 0.5}};
    scene.stop_lines = {{{14, -1.6}, {14, 1.6}, kBevLightRed}};
  }
};

using Bytes = std::vector<uint8_t>;

Bytes render(const BevRenderer& r, const BevScene& scene, const SensorShift* shift,
             uint64_t key) {
  Bytes out(r.frame_bytes(), 7);  // not 0 or 255: every byte must be written
  render_sensor(r, scene, shift, key, out.data());
  return out;
}

size_t plane_count(const BevRenderer& r, const Bytes& frame, int channel) {
  const size_t n = size_t(r.config().height) * r.config().width;
  size_t k = 0;
  for (size_t i = 0; i < n; ++i) k += frame[channel * n + i] != 0;
  return k;
}

bool plane_equal(const BevRenderer& r, const Bytes& a, const Bytes& b, int channel) {
  const size_t n = size_t(r.config().height) * r.config().width;
  return std::equal(a.begin() + channel * n, a.begin() + (channel + 1) * n, b.begin() + channel * n);
}

TEST(SensorShift, CleanIsTheRenderersOwnFrame) {
  Road road;
  BevRenderer r(road.map, BevConfig{});
  Bytes plain(r.frame_bytes());
  r.render(road.scene, plain.data());
  EXPECT_EQ(render(r, road.scene, nullptr, 12345), plain);
  EXPECT_GT(plane_count(r, plain, kBevVehicles), 0u) << "the scene must show cars";
}

TEST(SensorShift, SameKeySameBytesOtherSeedOrFrameOtherBytes) {
  Road road;
  BevRenderer r(road.map, BevConfig{});
  Bytes clean = render(r, road.scene, nullptr, 0);
  SensorShift s;  // the defaults of eval.sensor_*
  s.seed = 3;
  const uint64_t key = sensor_frame_key(s.seed, 777, 5);
  Bytes a = render(r, road.scene, &s, key), b = render(r, road.scene, &s, key);
  EXPECT_EQ(a, b) << "same seed, task, trial and frame: same bytes";
  EXPECT_NE(a, clean) << "the shifted sensor shows the clean frame";
  for (uint8_t v : a) ASSERT_TRUE(v == 0 || v == 255) << "channels stay 0/255";

  // Another frame of the episode, another trial (traffic seed), another sensor seed.
  EXPECT_NE(render(r, road.scene, &s, sensor_frame_key(s.seed, 777, 6)), a);
  EXPECT_NE(render(r, road.scene, &s, sensor_frame_key(s.seed, 778, 5)), a);
  SensorShift other = s;
  other.seed = 4;
  Bytes c = render(r, road.scene, &other, sensor_frame_key(other.seed, 777, 5));
  EXPECT_NE(c, a);
  EXPECT_FALSE(plane_equal(r, a, c, kBevMarkings)) << "worn paint depends on the seed";

  // What the task is stays: drivable area, route and the light are the clean ones.
  for (int ch : {kBevDrivable, kBevRoute, kBevLightRed, kBevLightGreen, kBevLightYield})
    EXPECT_TRUE(plane_equal(r, a, clean, ch)) << "channel " << bev_channel_names()[ch];
}

TEST(SensorShift, ZeroStrengthIsTheCleanFrame) {
  Road road;
  BevRenderer r(road.map, BevConfig{});
  SensorShift none{9, 0.0, 0.0, 0.0, 0.0};
  EXPECT_EQ(render(r, road.scene, &none, 42), render(r, road.scene, nullptr, 42));
}

TEST(SensorShift, EachKindOfNoiseDoesWhatItSays) {
  Road road;
  BevRenderer r(road.map, BevConfig{});
  Bytes clean = render(r, road.scene, nullptr, 0);

  // Every box missed, no ghosts: no road user is drawn; the paint is untouched.
  SensorShift blind{1, 1.0, 0.0, 0.0, 0.0};
  Bytes b = render(r, road.scene, &blind, 1);
  EXPECT_EQ(plane_count(r, b, kBevVehicles), 0u);
  EXPECT_EQ(plane_count(r, b, kBevPedestrians), 0u);
  EXPECT_TRUE(plane_equal(r, b, clean, kBevMarkings));

  // Jitter only: as many boxes, moved (the scene's boxes are the clean ones, moved).
  SensorShift shaky{1, 0.0, 1.0, 0.0, 0.0};
  BevScene js = shift_scene(road.scene, shaky, r.config(), 5);
  ASSERT_EQ(js.vehicles.size(), road.scene.vehicles.size());
  ASSERT_EQ(js.pedestrians.size(), road.scene.pedestrians.size());
  double moved = 0;
  for (size_t i = 0; i < js.vehicles.size(); ++i) {
    moved += (js.vehicles[i].center - road.scene.vehicles[i].center).norm();
    EXPECT_EQ(js.vehicles[i].length, road.scene.vehicles[i].length);
  }
  EXPECT_GT(moved, 0.3);
  EXPECT_LT(moved, 3 * 6.0) << "jitter of sd 1 m moved three boxes implausibly far";

  // Ghosts only, on an empty road: some frames show boxes that are not there, in view.
  BevScene empty;
  empty.ego = road.scene.ego;
  SensorShift haunted{1, 0.0, 0.0, 3.0, 0.0};
  int frames_with_ghosts = 0;
  size_t ghosts = 0;
  for (uint64_t f = 0; f < 20; ++f) {
    BevScene g = shift_scene(empty, haunted, r.config(), sensor_frame_key(1, 9, f));
    ghosts += g.vehicles.size() + g.pedestrians.size();
    Bytes frame = render(r, empty, &haunted, sensor_frame_key(1, 9, f));
    frames_with_ghosts += plane_count(r, frame, kBevVehicles) + plane_count(r, frame, kBevPedestrians) > 0;
    const BevConfig& cfg = r.config();
    for (const Box& box : g.vehicles) {  // inside the view rectangle around the ego
      EXPECT_LE(box.center.x, cfg.height * cfg.ego_row_fraction * cfg.metres_per_pixel + 1e-9);
      EXPECT_GE(box.center.x, -cfg.height * (1 - cfg.ego_row_fraction) * cfg.metres_per_pixel - 1e-9);
      EXPECT_LE(std::abs(box.center.y), cfg.width / 2.0 * cfg.metres_per_pixel + 1e-9);
    }
  }
  EXPECT_GT(frames_with_ghosts, 10) << "Poisson(3) ghosts are in most frames";
  EXPECT_GT(ghosts, 30u);
  EXPECT_LT(ghosts, 100u) << "about 3 ghosts a frame";

  // Worn paint only: fewer marking pixels, never new ones, the same wherever the ego is
  // (fixed on the road: the frame 4 m further on shows the same worn cells 8 pixels lower).
  SensorShift worn{1, 0.0, 0.0, 0.0, 0.5};
  Bytes w = render(r, road.scene, &worn, 1);
  const size_t before = plane_count(r, clean, kBevMarkings), after = plane_count(r, w, kBevMarkings);
  EXPECT_LT(after, before * 8 / 10);
  EXPECT_GT(after, before * 2 / 10);
  const size_t n = size_t(r.config().height) * r.config().width;
  for (size_t i = 0; i < n; ++i) {
    if (w[kBevMarkings * n + i]) {
      ASSERT_TRUE(clean[kBevMarkings * n + i]) << "paint added at " << i;
    }
  }
  BevScene ahead = road.scene;
  ahead.ego.pos = {4.0, 0.0};
  Bytes w2 = render(r, ahead, &worn, 2);
  const int W = r.config().width, shift_rows = int(4.0 / r.config().metres_per_pixel);
  size_t same = 0, compared = 0;
  for (int row = 0; row + shift_rows < r.config().height; ++row)
    for (int c = 0; c < W; ++c) {
      const size_t i = kBevMarkings * n + size_t(row) * W + c;
      const size_t j = kBevMarkings * n + size_t(row + shift_rows) * W + c;
      if (!clean[i]) continue;  // compare where there is paint in the clean frame
      ++compared;
      same += (w[i] != 0) == (w2[j] != 0);
    }
  ASSERT_GT(compared, 50u);
  EXPECT_GT(same, compared * 95 / 100) << "worn cells moved with the ego";
}

}  // namespace
}  // namespace cd
