// needs: sumo (the front camera's GL context comes with the driving world's build)
// The front camera (SPEC section 16): geometry computed by hand from the pixel convention of
// sense/camera.hpp, never golden images.
#include "sense/camera.hpp"

#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <cmath>
#include <map>
#include <string>
#include <vector>

#include "../support/test_support.hpp"
#include "core/error.hpp"

namespace cd {
namespace {

// 288 x 80, hfov 90: f = 144, centre (row 40, col 144); the camera 0.8 m ahead of the ego's
// centre, 1.4 m up, level.
// The tests below draw in one named weather (the default is the training pool).
CameraConfig config() {
  CameraConfig c;
  c.weather = "clear-noon";
  return c;
}

struct Pixel {
  int r, g, b;
};

class Frame {
 public:
  Frame(const CameraConfig& c, std::vector<uint8_t> bytes) : c_(c), bytes_(std::move(bytes)) {}
  Pixel at(int row, int col) const {
    const size_t plane = size_t(c_.width) * c_.height, o = size_t(row) * c_.width + col;
    return {bytes_[o], bytes_[plane + o], bytes_[2 * plane + o]};
  }
  Pixel at(const PixelPoint& p) const { return at(int(std::floor(p.row)), int(std::floor(p.col))); }
  const std::vector<uint8_t>& bytes() const { return bytes_; }

 private:
  CameraConfig c_;
  std::vector<uint8_t> bytes_;
};

Frame render(CameraRenderer& renderer, const CameraScene& scene) {
  std::vector<uint8_t> out(renderer.frame_bytes());
  renderer.render(scene, out.data());
  return Frame(renderer.config(), std::move(out));
}

bool reddish(Pixel p) { return p.r > 60 && p.r > 2 * p.g && p.r > 2 * p.b; }

CameraScene::Vehicle red_car(Vec2 centre) {
  CameraScene::Vehicle v;
  v.box = Box{centre, 0.0, 4.0, 2.0};
  v.height = 1.5;
  v.colour = 0xff0000;
  return v;
}

// An ego at the origin heading east, a red car 12 m ahead of its centre.
CameraScene car_ahead() {
  CameraScene scene;
  scene.ego = Pose2{{0, 0}, 0.0};
  scene.vehicles.push_back(red_car({12, 0}));
  return scene;
}

TEST(CameraGeometry, ProjectsAsComputedByHand) {
  const CameraConfig c = config();
  const Pose2 east{{10, 20}, 0.0};
  // 10 m ahead of the camera at its own height: the image centre.
  auto p = camera_project(c, east, {20.8, 20}, 1.4);
  ASSERT_TRUE(p);
  EXPECT_NEAR(p->row, 40, 1e-9);
  EXPECT_NEAR(p->col, 144, 1e-9);
  EXPECT_NEAR(p->depth, 10, 1e-9);
  // 1 m to the left on the ground: col 144 - 144 * 1/10, row 40 + 144 * 1.4/10.
  p = camera_project(c, east, {20.8, 21}, 0.0);
  EXPECT_NEAR(p->col, 129.6, 1e-9);
  EXPECT_NEAR(p->row, 60.16, 1e-9);
  // Heading north: forward is +y, left is -x.
  const Pose2 north{{0, 0}, M_PI / 2};
  p = camera_project(c, north, {-2, 10.8}, 1.4);
  EXPECT_NEAR(p->col, 144 - 144 * 2 / 10.0, 1e-9);
  EXPECT_NEAR(p->row, 40, 1e-9);
  // Behind the camera: nothing.
  EXPECT_FALSE(camera_project(c, east, {5, 20}, 1.0));
  // Pitched 10 degrees down: a point on the optical axis is the centre, 8 m along it.
  CameraConfig pitched = c;
  pitched.pitch_deg = 10;
  const double t = 10 * M_PI / 180;
  p = camera_project(pitched, east, {10.8 + 8 * std::cos(t), 20}, 1.4 - 8 * std::sin(t));
  EXPECT_NEAR(p->row, 40, 1e-9);
  EXPECT_NEAR(p->col, 144, 1e-9);
  EXPECT_NEAR(p->depth, 8, 1e-9);
  // CILRS's 200 x 88 is one setting away: f = 100 at 90 degrees.
  CameraConfig cilrs = c;
  cilrs.width = 200;
  cilrs.height = 88;
  p = camera_project(cilrs, east, {20.8, 21}, 1.4);
  EXPECT_NEAR(p->col, 100 - 100 * 0.1, 1e-9);
  EXPECT_NEAR(p->row, 44, 1e-9);
}

TEST(CameraRender, ABoxLandsOnThePixelsItsProjectionGives) {
  RoadMap none;
  CameraRenderer renderer(none, config());
  const CameraScene scene = car_ahead();
  const Pose2 ego = scene.ego;
  const Frame f = render(renderer, scene);
  // The box's silhouette from behind is the bounding box of its corners' projections.
  double r0 = 1e9, r1 = -1e9, c0 = 1e9, c1 = -1e9;
  for (double x : {10.0, 14.0})
    for (double y : {-1.0, 1.0})
      for (double z : {0.0, 1.5}) {
        const auto p = camera_project(renderer.config(), ego, {x, y}, z);
        ASSERT_TRUE(p);
        r0 = std::min(r0, p->row), r1 = std::max(r1, p->row);
        c0 = std::min(c0, p->col), c1 = std::max(c1, p->col);
      }
  // By hand for the rear face, 9.2 m from the camera: cols 144 -+ 144/9.2, rows 40 - 14.4/9.2
  // to 40 + 201.6/9.2.
  EXPECT_NEAR(c0, 144 - 144 / 9.2, 1e-9);
  EXPECT_NEAR(r1, 40 + 201.6 / 9.2, 1e-9);
  int inside = 0, outside = 0;
  for (int r = 0; r < 80; ++r)
    for (int c = 0; c < 288; ++c) {
      const double rc = r + 0.5, cc = c + 0.5;
      const bool in = rc > r0 + 1 && rc < r1 - 1 && cc > c0 + 1 && cc < c1 - 1;
      const bool out = rc < r0 - 1 || rc > r1 + 1 || cc < c0 - 1 || cc > c1 + 1;
      if (in) {
        ++inside;
        EXPECT_TRUE(reddish(f.at(r, c))) << r << "," << c;
      } else if (out) {
        ++outside;
        EXPECT_FALSE(reddish(f.at(r, c))) << r << "," << c;
      }
    }
  EXPECT_GT(inside, 300);
  EXPECT_GT(outside, 20000);
  // Above the horizon the sky, below it the ground, in the weather's colours.
  const CameraWeather& w = camera_weather("clear-noon");
  const Pixel sky = f.at(5, 5), ground = f.at(75, 5);
  EXPECT_NEAR(sky.b, std::lround(w.sky[2] * 255), 1);
  EXPECT_NEAR(ground.g, std::lround(w.ground[1] * 255), 1);
}

TEST(CameraRender, ALeaderAt10mCoversMorePixelsThanAt30m) {
  RoadMap none;
  CameraRenderer renderer(none, config());
  auto red_pixels = [&](double ahead) {
    CameraScene scene;
    scene.ego = Pose2{{0, 0}, 0.0};
    scene.vehicles.push_back(red_car({ahead, 0}));
    const Frame f = render(renderer, scene);
    int n = 0;
    for (int r = 0; r < 80; ++r)
      for (int c = 0; c < 288; ++c) n += reddish(f.at(r, c));
    return n;
  };
  const int near = red_pixels(10.8 + 2), far = red_pixels(30.8 + 2);
  EXPECT_GT(far, 20);
  // The rear face's area goes as 1/depth^2: 9x from 30 to 10 m.
  EXPECT_GT(near, 6 * far) << near << " vs " << far;
  EXPECT_LT(near, 14 * far) << near << " vs " << far;
}

TEST(CameraRender, TheLitLampFollowsTheLightAndIsAFewPixelsAt30m) {
  RoadMap none;
  CameraRenderer renderer(none, config());
  const Pose2 ego{{0, 0}, 0.0};
  const LightHeadGeometry& g = kLightHead;
  for (double ahead : {15.8, 30.8}) {
    CameraScene::Light light;
    light.position = {ahead, 3.0};
    light.facing = M_PI;  // looking back at the ego
    const Vec2 face = light.position - Vec2{0.5 * g.head_depth + 0.01, 0};
    auto lamp = [&](int k) {
      return *camera_project(renderer.config(), ego, face, g.lamp_centre_height(k));
    };
    // Its size in pixels: f * lamp_size / depth, about 1.1 px at 30 m.
    const double px = 144 * g.lamp_size / (ahead - 0.8);
    EXPECT_LT(px, ahead > 20 ? 1.5 : 3.0);
    for (char state : {'r', 'y', 'g'}) {
      CameraScene scene;
      scene.ego = ego;
      light.state = state;
      scene.lights = {light};
      const Frame f = render(renderer, scene);
      const Pixel red = f.at(lamp(0)), yellow = f.at(lamp(1)), green = f.at(lamp(2));
      if (ahead > 20) {  // at 30 m only the lit lamp's hue is asked of its pixel
        if (state == 'r') {
          EXPECT_GT(red.r, 2 * red.g) << ahead;
        }
        if (state == 'g') {
          EXPECT_GT(green.g, 2 * green.r) << ahead;
        }
        continue;
      }
      if (state == 'r') {
        EXPECT_GT(red.r, 200);
        EXPECT_LT(red.g, 60);
        EXPECT_LT(green.g, 60);
      } else if (state == 'y') {
        EXPECT_GT(yellow.r, 200);
        EXPECT_GT(yellow.g, 150);
        EXPECT_LT(yellow.b, 60);
        EXPECT_LT(red.r, 60);
      } else {
        EXPECT_GT(green.g, 200);
        EXPECT_LT(green.r, 80);
        EXPECT_LT(red.r, 60);
      }
    }
  }
}

TEST(CameraRender, BrakeLightsLightWhenTheLeaderBrakes) {
  RoadMap none;
  CameraRenderer renderer(none, config());
  CameraScene scene = car_ahead();
  const Pose2 ego = scene.ego;
  scene.vehicles[0].colour = 0x2040c0;  // a blue car, so the lamp's red stands out
  // The left lamp's centre: 0.02 m behind the rear face, 0.75 m left, 0.85 m up.
  const auto p = *camera_project(renderer.config(), ego, {12 - 2.02, 0.75}, 0.85);
  const Pixel off = render(renderer, scene).at(p);
  scene.vehicles[0].braking = true;
  const Pixel on = render(renderer, scene).at(p);
  EXPECT_GT(on.r, 230);
  EXPECT_LT(off.r, 100);
  EXPECT_GT(off.r, 2 * off.b);  // dark red, not the car's blue
}

// One 3.2 m driving lane along the x axis, from x = -50 to 200 m.
RoadMap one_lane_map(Vec2 from = {-50, 0}, Vec2 to = {200, 0}) {
  RoadMap map;
  LaneGeom lane;
  lane.id = "a_0";
  lane.edge = "a";
  lane.width = 3.2;
  lane.shape = {from, to};
  map.add(lane);
  return map;
}

// The frame of an empty road seen from `ego`.
Frame render_empty(CameraRenderer& renderer, Pose2 ego) {
  CameraScene scene;
  scene.ego = ego;
  return render(renderer, scene);
}

TEST(CameraRender, RoadsMarkingsAndGroundWhereTheMapPutsThem) {
  const RoadMap map = one_lane_map();
  CameraRenderer renderer(map, config());
  const Pose2 ego{{0, 0}, 0.0};
  const Frame f = render_empty(renderer, ego);
  const CameraWeather& w = camera_weather("clear-noon");
  auto is = [](Pixel p, const float c[3]) {
    return std::abs(p.r - std::lround(c[0] * 255)) <= 1 &&
           std::abs(p.g - std::lround(c[1] * 255)) <= 1 &&
           std::abs(p.b - std::lround(c[2] * 255)) <= 1;
  };
  // The lane's centre 10 m ahead, and 6 m to its left (off the road).
  EXPECT_TRUE(is(f.at(*camera_project(renderer.config(), ego, {10.8, 0}, 0)), w.road));
  EXPECT_TRUE(is(f.at(*camera_project(renderer.config(), ego, {10.8, 6}, 0)), w.ground));
  // The right border is a solid line (no right neighbour): every 1 m from 6 to 12 m.
  for (double x = 6; x <= 12; x += 1)
    EXPECT_TRUE(is(f.at(*camera_project(renderer.config(), ego, {x + 0.8, -1.6}, 0)), w.marking))
        << x;
  // The left border is dashed: 3 m painted around multiples of 6 m, 3 m gap around 3 + 6k.
  EXPECT_TRUE(is(f.at(*camera_project(renderer.config(), ego, {12.0, 1.6}, 0)), w.marking));
  // In a gap the border is the road's edge: its pixel is the road's or the ground's colour.
  const Pixel gap = f.at(*camera_project(renderer.config(), ego, {9.0, 1.6}, 0));
  EXPECT_TRUE(is(gap, w.road) || is(gap, w.ground)) << gap.r << " " << gap.g << " " << gap.b;
}

// Every pixel below the horizon, by hand: its centre's ray meets the ground at a point the pixel
// convention gives (level camera: depth = f * 1.4 / (row + 0.5 - cy)), and the pixel shows the
// layer under that point: the road inside the lane, the solid right border, the ground beside it,
// no paint beyond 80 m; the colour is the weather's, fogged by GL_EXP over the eye depth. Margins
// of 4 cm from every edge allow for the 5 cm texels.
TEST(CameraRender, EachPixelShowsTheLayerWhereItsRayMeetsTheGround) {
  const RoadMap map = one_lane_map();  // y in [-1.6, 1.6], x from -50 to 200
  for (const char* name : {"clear-noon", "hard-rain-noon"}) {
    CameraConfig c = config();
    c.weather = name;
    CameraRenderer renderer(map, c);
    const CameraWeather& w = camera_weather(name);
    const Frame frame = render_empty(renderer, Pose2{{3, -0.4}, 0.05});
    const double f = 144, cx = 144, cy = 40, ch = std::cos(0.05), sh = std::sin(0.05);
    const double camx = 3 + 0.8 * ch, camy = -0.4 + 0.8 * sh;
    long road = 0, ground = 0, marking = 0, far_road = 0;
    for (int row = 0; row < 80; ++row)
      for (int col = 0; col < 288; ++col) {
        const Pixel p = frame.at(row, col);
        if (row + 0.5 <= cy) {  // above the horizon: the sky
          ASSERT_EQ(p.r, std::lround(w.sky[0] * 255)) << row << " " << col;
          continue;
        }
        const double depth = f * 1.4 / (row + 0.5 - cy), right = (col + 0.5 - cx) * depth / f;
        const double x = camx + depth * ch + right * sh, y = camy + depth * sh - right * ch;
        const double dist = std::hypot(depth, right);
        const float* want = nullptr;
        if (x < -49.9 || x > 199.9) continue;
        if (dist <= 79.5) {
          if (std::abs(y) < 1.48) want = w.road, ++road;
          else if (std::abs(y) > 1.72) want = w.ground, ++ground;
          else if (std::abs(y + 1.6) < 0.03) want = w.marking, ++marking;
        } else if (dist >= 80.5 && dist <= 299) {
          if (std::abs(y) < 1.55) want = w.road, ++far_road;
          else if (std::abs(y) > 1.65) want = w.ground, ++ground;
        }
        if (want == nullptr) continue;
        const double keep = std::exp(-w.fog_density * depth);
        for (int k = 0; k < 3; ++k) {
          const double v = keep * want[k] + (1 - keep) * w.sky[k];
          const int got = k == 0 ? p.r : k == 1 ? p.g : p.b;
          ASSERT_LE(std::abs(got - std::lround(v * 255)), 1)
              << name << " row " << row << " col " << col << " at (" << x << ", " << y << ")";
        }
      }
    EXPECT_GT(road, 1000) << name;
    EXPECT_GT(ground, 5000) << name;
    EXPECT_GT(marking, 20) << name;
    EXPECT_GE(far_road, 5) << name;  // two rows, 3-5 pixels of lane each
  }
}

// A network over 1.6 km on a side gets coarser texels (10 cm for 3.3 km) rather than a raster of
// gigabytes: a 5 km lane (15 cm texels) still shows its road and the ground beside it.
TEST(CameraRender, AFiveKilometreLaneStillShowsWhereItIs) {
  CameraRenderer renderer(one_lane_map({0, 0}, {5000, 0}), config());
  const Pose2 ego{{4200, 0}, 0.0};
  const Frame f = render_empty(renderer, ego);
  const CameraWeather& w = camera_weather("clear-noon");
  const Pixel road = f.at(*camera_project(renderer.config(), ego, {4212, 0.3}, 0));
  const Pixel ground = f.at(*camera_project(renderer.config(), ego, {4212, 6}, 0));
  EXPECT_EQ(road.g, std::lround(w.road[1] * 255));
  EXPECT_EQ(ground.g, std::lround(w.ground[1] * 255));
}

TEST(CameraRender, SameSceneSameBytesAndTheWeatherChangesThem) {
  RoadMap none;
  CameraRenderer renderer(none, config());
  CameraScene scene;
  scene.ego = Pose2{{0, 0}, 0.3};
  scene.vehicles.push_back(red_car({14, 4}));
  scene.lights.push_back({{20, 6}, M_PI, 'g'});
  const Frame a = render(renderer, scene);
  EXPECT_EQ(a.bytes(), render(renderer, scene).bytes());
  CameraConfig rain = config();
  rain.weather = "hard-rain-noon";
  CameraRenderer wet(none, rain);
  const Frame b = render(wet, scene);
  EXPECT_NE(a.bytes(), b.bytes());
  EXPECT_EQ(b.bytes(), render(wet, scene).bytes());
}

// The pixels a scene's road users cover: where the frame differs from the same camera's frame
// of the empty road.
std::vector<bool> covered(CameraRenderer& renderer, const CameraScene& scene) {
  CameraScene empty;
  empty.ego = scene.ego;
  const Frame with = render(renderer, scene), without = render(renderer, empty);
  const CameraConfig& c = renderer.config();
  std::vector<bool> mask(size_t(c.width) * c.height);
  for (int row = 0; row < c.height; ++row)
    for (int col = 0; col < c.width; ++col) {
      const Pixel a = with.at(row, col), b = without.at(row, col);
      mask[size_t(row) * c.width + col] = a.r != b.r || a.g != b.g || a.b != b.b;
    }
  return mask;
}

int threads_of_this_process() {
  int n = 0;
  for ([[maybe_unused]] const auto& e : std::filesystem::directory_iterator("/proc/self/task")) ++n;
  return n;
}

// collect and eval make the world (and its camera) in a worker, then fork each episode's
// process from it (core/worker_pool): a GL context must start no thread a child would lose
// (Mesa's shader-cache thread once hung a collection), and the child must render the parent's
// bytes.
TEST(CameraFork, AContextStartsNoThreadAndAForkedChildRendersTheSameBytes) {
  const int before = threads_of_this_process();
  RoadMap none;
  CameraRenderer renderer(none, config());
  const Frame parent = render(renderer, car_ahead());
  EXPECT_EQ(threads_of_this_process(), before);
  for (int child = 0; child < 3; ++child) {
    const pid_t pid = fork();
    ASSERT_GE(pid, 0);
    if (pid == 0) {
      CameraScene scene = car_ahead();
      scene.vehicles[0].colour = 0x00ff00;  // a new colour: GL draws again, not a cached frame
      render(renderer, scene);
      _exit(render(renderer, car_ahead()).bytes() == parent.bytes() ? 0 : 3);
    }
    int status = 0;
    if (!test::wait_child(pid, 60, &status)) {
      kill(pid, SIGKILL);
      waitpid(pid, &status, 0);
      FAIL() << "the forked child did not finish rendering in 60 s (a GL lock held by a lost "
                "thread?)";
    }
    ASSERT_TRUE(WIFEXITED(status));
    EXPECT_EQ(WEXITSTATUS(status), 0) << "the child's frame differs from the parent's";
  }
}

TEST(CameraRender, AWeatherChangesTheColoursButNotWhereAnythingIs) {
  RoadMap none;
  CameraScene scene = car_ahead();
  scene.vehicles.push_back(red_car({25, -4}));
  scene.lights.push_back({{20, 6}, M_PI, 'g'});
  CameraRenderer noon(none, config());
  const std::vector<bool> at_noon = covered(noon, scene);
  const long n = std::count(at_noon.begin(), at_noon.end(), true);
  EXPECT_GT(n, 200) << "two cars and a signal head in view";
  for (const char* name : {"wet-noon", "hard-rain-noon", "clear-sunset", "soft-rain-sunset",
                           "after-rain-dusk"}) {
    CameraConfig c = config();
    c.weather = name;
    CameraRenderer other(none, c);
    EXPECT_NE(render(other, scene).bytes(), render(noon, scene).bytes()) << name;
    EXPECT_EQ(covered(other, scene), at_noon) << name << ": the same pixels are covered";
  }
}

TEST(CameraRender, AVehicleBehindTheCameraNeverShows) {
  RoadMap none;
  CameraRenderer renderer(none, config());
  CameraScene scene;
  scene.ego = Pose2{{0, 0}, 0.0};  // the camera at x = 0.8, looking east
  // Behind it: just behind the lens, farther back, beside and behind, and a signal head.
  for (Vec2 at : {Vec2{-2.5, 0}, Vec2{-12, 0}, Vec2{-6, 3.5}, Vec2{-30, -4}})
    scene.vehicles.push_back(red_car(at));
  scene.lights.push_back({{-8, 3}, 0.0, 'r'});
  const std::vector<bool> mask = covered(renderer, scene);
  EXPECT_EQ(std::count(mask.begin(), mask.end(), true), 0);
}

TEST(CameraRender, ChangingTheWeatherRendersAsARendererMadeInIt) {
  // A lane, so the static layers' colours show: set_weather must recolour them too.
  const RoadMap map = one_lane_map();
  CameraScene scene = car_ahead();
  scene.lights.push_back({{20, 6}, M_PI, 'g'});
  CameraRenderer switched(map, config());
  const Frame noon = render(switched, scene);
  for (const char* name : {"after-rain-dusk", "clear-noon"}) {
    CameraConfig c = config();
    c.weather = name;
    CameraRenderer made(map, c);
    switched.set_weather(camera_weather(name));
    EXPECT_EQ(switched.weather().name, name);
    EXPECT_EQ(render(switched, scene).bytes(), render(made, scene).bytes()) << name;
  }
  EXPECT_EQ(render(switched, scene).bytes(), noon.bytes());
}

TEST(CameraWeathers, APoolGivesEachSeedOneOfItsSetsAndTheSameOneAgain) {
  std::map<std::string, int> train, held;
  for (uint64_t seed = 0; seed < 400; ++seed) {
    const CameraWeather& t = episode_weather(kTrainWeathers, seed);
    const CameraWeather& h = episode_weather(kHeldOutWeathers, seed);
    EXPECT_FALSE(t.held_out) << t.name;
    EXPECT_TRUE(h.held_out) << h.name;
    EXPECT_EQ(&t, &episode_weather(kTrainWeathers, seed));
    ++train[t.name];
    ++held[h.name];
  }
  // Every set of a pool is drawn, none far from its share (400 seeds: 100 or 200 expected).
  ASSERT_EQ(train.size(), 4u);
  ASSERT_EQ(held.size(), 2u);
  for (const auto& [name, n] : train) EXPECT_NEAR(n, 100, 40) << name;
  for (const auto& [name, n] : held) EXPECT_NEAR(n, 200, 50) << name;
  // A set's name is that set whatever the seed; the default setting is the training pool.
  EXPECT_EQ(episode_weather("wet-noon", 12345).name, "wet-noon");
  EXPECT_EQ(CameraConfig{}.weather, kTrainWeathers);
  try {
    episode_weather("rainy", 1);
    FAIL() << "an unknown setting was accepted";
  } catch (const ConfigError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("'rainy' (known: train, held-out, clear-noon"), std::string::npos) << what;
  }
}

TEST(CameraWeathers, FourTrainTwoHeldOutAndUnknownNamesAreOneLine) {
  int held = 0;
  for (const CameraWeather& w : camera_weathers()) held += w.held_out;
  EXPECT_EQ(camera_weathers().size(), 6u);
  EXPECT_EQ(held, 2);
  try {
    camera_weather("foggy-moon");
    FAIL() << "an unknown weather was accepted";
  } catch (const ConfigError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("foggy-moon"), std::string::npos) << what;
    EXPECT_NE(what.find("clear-noon"), std::string::npos) << what;
    EXPECT_EQ(what.find('\n'), std::string::npos) << what;
  }
  RoadMap none;
  CameraConfig bad = config();
  bad.hfov_deg = 200;
  EXPECT_THROW(CameraRenderer(none, bad), ConfigError);
  bad = config();
  bad.width = 4;
  EXPECT_THROW(check_camera_config(bad), ConfigError);
  bad = config();
  bad.weather = "nope";
  EXPECT_THROW(check_camera_config(bad), ConfigError);
}

}  // namespace
}  // namespace cd
