// needs: sumo
// The live world through the front camera (World::camera_scene, SPEC section 16): the signal
// head on the ego's approach shows the ego's next light and is drawn where the projection puts
// it; a car that brakes lights its brake lights.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <set>
#include <string>
#include <vector>

#include "app/settings.hpp"
#include "sense/camera.hpp"
#include "../support/test_support.hpp"
#include "world/world.hpp"

namespace cd {
namespace {

using test::TempDir;

Settings empty_town() {
  TempDir dir("cdtest-world-camera");
  return load_settings(test::write_test_config(dir, "empty"));
}

struct Pixel {
  int r, g, b;
};
Pixel pixel_at(const std::vector<uint8_t>& f, const CameraConfig& c, const PixelPoint& p) {
  const size_t plane = size_t(c.width) * c.height;
  const size_t o = size_t(std::floor(p.row)) * c.width + size_t(std::floor(p.col));
  return {f[o], f[plane + o], f[2 * plane + o]};
}

TEST(WorldCamera, EverySignalisedApproachHasOneHeadFacingBackAlongIt) {
  CD_NEEDS_SUMO();
  World w(empty_town());
  const std::vector<SignalHead> heads = find_signal_heads(w.network());
  ASSERT_FALSE(heads.empty()) << "town-a has signalised junctions";
  std::set<std::string> approaches;
  for (const SignalHead& h : heads) {
    EXPECT_TRUE(approaches.insert(h.approach).second) << h.approach << " has two heads";
    ASSERT_NE(h.via, nullptr);
    EXPECT_FALSE(h.via->tls.empty());
    EXPECT_EQ(h.via->approach, h.approach);
    // 0.6 m beyond the lane's right edge at its end, facing back along the lane.
    const LaneGeom* lane = w.map().find(h.approach);
    ASSERT_NE(lane, nullptr);
    const Vec2 end = lane->shape.back(), before = lane->shape[lane->shape.size() - 2];
    EXPECT_NEAR((h.pole - end).norm(), 0.5 * lane->width + 0.6, 1e-6);
    const Vec2 d = end - before;
    EXPECT_NEAR(std::cos(h.facing) * d.x + std::sin(h.facing) * d.y, -d.norm(), 1e-6);
  }
  EXPECT_TRUE(std::is_sorted(heads.begin(), heads.end(),
                             [](const SignalHead& a, const SignalHead& b) {
                               return a.approach < b.approach;
                             }));
}

TEST(WorldCamera, TheHeadAheadShowsTheEgosNextLightWhereTheProjectionPutsIt) {
  CD_NEEDS_SUMO();
  const Settings s = empty_town();
  World w(s);
  CameraRenderer camera(w.map(), s.camera);
  std::vector<uint8_t> frame(camera.frame_bytes());
  int checked = 0;
  for (uint64_t seed = 0; seed < 40 && checked < 3; ++seed) {
    w.reset(w.sample_task(seed, 100, 250));
    for (int i = 0; i < 400; ++i) {
      const GroundTruth& t = w.truth();
      if (t.tl_state != kTlNone && t.tl_distance > 12 && t.tl_distance < 30) break;
      if (w.step(Control{0.6, 0.0}).outcome != Outcome::Running) break;
    }
    const GroundTruth& t = w.truth();
    if (t.tl_state == kTlNone || t.tl_distance <= 12 || t.tl_distance >= 30) continue;
    const CameraScene scene = w.camera_scene();
    const std::vector<SignalHead> heads = find_signal_heads(w.network());
    auto own = std::find_if(heads.begin(), heads.end(),
                            [&](const SignalHead& h) { return h.approach == w.ego().lane; });
    ASSERT_NE(own, heads.end()) << w.ego().lane;
    auto light = std::find_if(scene.lights.begin(), scene.lights.end(),
                              [&](const CameraScene::Light& l) {
                                return (l.position - own->pole).norm() < 1e-9;
                              });
    ASSERT_NE(light, scene.lights.end());
    const char want = t.tl_state == kTlRed ? 'r' : t.tl_state == kTlYellow ? 'y' : 'g';
    EXPECT_EQ(light->state, want) << "seed " << seed;
    // Its lit lamp on the image, when the projection puts it there.
    camera.render(scene, frame.data());
    const LightHeadGeometry& g = kLightHead;
    const int lamp = want == 'r' ? 0 : want == 'y' ? 1 : 2;
    const Vec2 face = light->position + Vec2{std::cos(light->facing), std::sin(light->facing)} *
                                            (0.5 * g.head_depth + 0.01);
    const auto p = camera_project(s.camera, scene.ego, face, g.lamp_centre_height(lamp));
    if (!p || p->row < 0 || p->row >= s.camera.height || p->col < 0 || p->col >= s.camera.width)
      continue;
    const Pixel px = pixel_at(frame, s.camera, *p);
    if (want == 'r') EXPECT_GT(px.r, 2 * px.g) << "seed " << seed;
    if (want == 'g') EXPECT_GT(px.g, 2 * px.r) << "seed " << seed;
    ++checked;
  }
  EXPECT_GT(checked, 0) << "no task came within 12-30 m of a light with its head in view";
}

TEST(WorldCamera, ACarThatBrakesLightsItsBrakeLights) {
  CD_NEEDS_SUMO();
  World w(empty_town());
  bool done = false;
  for (uint64_t seed = 0; seed < 20 && !done; ++seed) {
    w.reset(w.sample_task(seed, 100, 250));
    const LaneGeom* lane = w.map().find(w.ego().lane);
    if (!lane || lane->length < w.ego().lane_pos + 60) continue;
    const std::string id = w.add_scripted_vehicle(lane->id, w.ego().lane_pos + 20, 8.0);
    auto braking = [&] {
      for (const CameraScene::Vehicle& v : w.camera_scene().vehicles)
        if ((v.box.center - w.ego().pose.pos).norm() < 45) return v.braking;
      ADD_FAILURE() << "the scripted car is not in the camera's scene";
      return false;
    };
    for (int i = 0; i < 3; ++i) w.step(Control{0.0, 1.0});
    EXPECT_FALSE(braking()) << "at a steady 8 m/s";
    w.set_vehicle_speed(id, 0.0);
    w.step(Control{0.0, 1.0});
    EXPECT_TRUE(braking()) << "after its speed was set to 0";
    done = true;
  }
  EXPECT_TRUE(done) << "no task started on a lane long enough";
}

// sense.view = "camera": the World's frames are the front camera's (3 x H x W, named red, green,
// blue), the bytes a CameraRenderer draws of camera_scene(); render_from a pose 1.5 m to the
// side draws another picture, the same as the renderer's of that pose; a BEV world's frames
// stay the BEV's. The camera offers no bit planes.
TEST(WorldCamera, TheCameraViewRendersTheFrontCamera) {
  CD_NEEDS_SUMO();
  Settings s = empty_town();
  s.view = "camera";
  s.camera.width = 96;
  s.camera.height = 32;
  World w(s);
  const FrameFormat& f = w.frame_format();
  EXPECT_TRUE(w.camera_view());
  EXPECT_EQ(f.view, "camera");
  EXPECT_EQ(f.channels, 3);
  EXPECT_EQ(f.height, 32);
  EXPECT_EQ(f.width, 96);
  EXPECT_EQ(f.bytes(), 3u * 32 * 96);
  EXPECT_EQ(f.channel_names, camera_channel_names());
  const Task task = w.sample_task(3, 100, 200);
  w.reset(task);
  // The default weather is the training pool: the episode's set is drawn by its traffic seed.
  EXPECT_EQ(w.weather(), episode_weather(kTrainWeathers, task.traffic_seed).name);
  EXPECT_FALSE(camera_weather(w.weather()).held_out);
  for (int i = 0; i < 20; ++i) w.step(Control{0.5, 0.0});
  std::vector<uint8_t> frame(f.bytes()), oracle(f.bytes()), moved(f.bytes());
  w.render(frame.data());
  CameraConfig in_that_weather = s.camera;
  in_that_weather.weather = w.weather();
  CameraRenderer camera(w.map(), in_that_weather);
  CameraScene scene = w.camera_scene();
  camera.render(scene, oracle.data());
  EXPECT_EQ(frame, oracle);
  const Pose2 seen = shifted_pose(w.ego().pose, 1.5, 0.0);
  w.render_from(seen, moved.data());
  EXPECT_NE(moved, frame);
  scene.ego = seen;
  camera.render(scene, oracle.data());
  EXPECT_EQ(moved, oracle);
  std::vector<uint8_t> packed(f.pixels());
  EXPECT_THROW(w.render_packed(packed.data()), std::logic_error);
  // Episodes of other seeds draw other sets of the pool, each the one its seed gives.
  std::set<std::string> drawn;
  for (uint64_t seed = 10; seed < 18; ++seed) {
    const Task t = w.sample_task(seed, 100, 200);
    w.reset(t);
    EXPECT_EQ(w.weather(), episode_weather(kTrainWeathers, t.traffic_seed).name);
    drawn.insert(w.weather());
  }
  EXPECT_GE(drawn.size(), 2u);
}

TEST(WorldCamera, TheDefaultViewIsTheBev) {
  CD_NEEDS_SUMO();
  const Settings s = empty_town();
  EXPECT_EQ(s.view, "bev");
  World w(s);
  EXPECT_FALSE(w.camera_view());
  EXPECT_EQ(w.frame_format().view, "bev");
  EXPECT_EQ(w.frame_format().channels, static_cast<int>(kBevChannelCount));
  EXPECT_EQ(w.frame_format().height, s.bev.height);
  EXPECT_EQ(w.frame_format().metres_per_pixel, s.bev.metres_per_pixel);
}

}  // namespace
}  // namespace cd
