#include "sense/bev.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "core/error.hpp"

namespace cd {
namespace {

LaneGeom make_lane(const std::string& id, Polyline shape, LaneKind kind = LaneKind::Driving,
                   bool internal = false, bool left_nb = false, bool right_nb = false) {
  LaneGeom l;
  l.id = id;
  l.edge = id.substr(0, id.rfind('_'));
  l.kind = kind;
  l.internal = internal;
  l.width = 3.2;
  l.shape = std::move(shape);
  l.length = polyline_length(l.shape);
  l.has_left_neighbour = left_nb;
  l.has_right_neighbour = right_nb;
  return l;
}

// One road, one lane each way: E_0 eastbound on y = 0, W_0 westbound on y = 3.2.
RoadMap two_way_road() {
  RoadMap m;
  m.add(make_lane("E_0", {{-100, 0}, {100, 0}}));
  m.add(make_lane("W_0", {{100, 3.2}, {-100, 3.2}}));
  return m;
}

// One eastbound edge with two lanes: E_0 centred on y = -1.6, E_1 on y = 1.6, so the
// divider is y = 0 and the outer (solid) border y = -3.2.
RoadMap two_lane_edge() {
  RoadMap m;
  m.add(make_lane("E_0", {{-100, -1.6}, {100, -1.6}}, LaneKind::Driving, false, true, false));
  m.add(make_lane("E_1", {{-100, 1.6}, {100, 1.6}}, LaneKind::Driving, false, false, true));
  return m;
}

struct Frame {
  BevConfig cfg;
  std::vector<uint8_t> data;
  explicit Frame(const BevConfig& c) : cfg(c), data(size_t(kBevChannelCount) * c.height * c.width) {}
  uint8_t at(int ch, int r, int c) const {
    return data[(size_t(ch) * cfg.height + r) * cfg.width + c];
  }
};

Frame render(const BevRenderer& bev, const BevScene& scene) {
  Frame f(bev.config());
  bev.render(scene, f.data.data());
  return f;
}

// Network coordinates of the centre of output pixel (r, c), from the header's convention.
Vec2 pixel_centre(const BevConfig& cfg, const Pose2& ego, int r, int c) {
  const double forward = (cfg.height * cfg.ego_row_fraction - (r + 0.5)) * cfg.metres_per_pixel;
  const double left = (cfg.width / 2.0 - (c + 0.5)) * cfg.metres_per_pixel;
  const Vec2 f{std::cos(ego.heading), std::sin(ego.heading)};
  const Vec2 l{-std::sin(ego.heading), std::cos(ego.heading)};
  return ego.pos + f * forward + l * left;
}

Vec2 ahead_left(const Pose2& ego, double forward, double left) {
  const Vec2 f{std::cos(ego.heading), std::sin(ego.heading)};
  const Vec2 l{-std::sin(ego.heading), std::cos(ego.heading)};
  return ego.pos + f * forward + l * left;
}

// Signed clearance of p inside the box (negative: outside), in metres.
double box_clearance(const Box& b, Vec2 p) {
  const Vec2 u{std::cos(b.heading), std::sin(b.heading)}, v{-u.y, u.x};
  const Vec2 d = p - b.center;
  return std::min(b.length / 2 - std::abs(d.dot(u)), b.width / 2 - std::abs(d.dot(v)));
}

// Asserts that the channel holds 255 exactly at the pixels whose centres lie in one of the
// boxes and 0 elsewhere.
void expect_exact_boxes(const Frame& f, int ch, const Pose2& ego, const std::vector<Box>& boxes) {
  int inside_count = 0;
  for (int r = 0; r < f.cfg.height; ++r)
    for (int c = 0; c < f.cfg.width; ++c) {
      const Vec2 p = pixel_centre(f.cfg, ego, r, c);
      bool inside = false;
      for (const Box& b : boxes) {
        const double cl = box_clearance(b, p);
        ASSERT_GT(std::abs(cl), 1e-6) << "test pose puts a pixel centre on a box edge";
        inside = inside || cl > 0;
      }
      inside_count += inside;
      EXPECT_EQ(f.at(ch, r, c), inside ? 255 : 0) << "pixel " << r << "," << c;
    }
  EXPECT_GT(inside_count, 0);
}

TEST(Bev, ChannelNames) {
  const auto& n = bev_channel_names();
  ASSERT_EQ(n.size(), size_t(kBevChannelCount));
  EXPECT_EQ(kBevChannelCount, 8);
  EXPECT_EQ(n[kBevDrivable], "drivable");
  EXPECT_EQ(n[kBevMarkings], "markings");
  EXPECT_EQ(n[kBevRoute], "route");
  EXPECT_EQ(n[kBevVehicles], "vehicles");
  EXPECT_EQ(n[kBevPedestrians], "pedestrians");
  EXPECT_EQ(n[kBevLightRed], "light_red");
  EXPECT_EQ(n[kBevLightGreen], "light_green");
  EXPECT_EQ(n[kBevLightYield], "light_yield");
}

TEST(Bev, FrameBytes) {
  const RoadMap m = two_way_road();
  BevConfig cfg;
  cfg.height = 40;
  cfg.width = 30;
  BevRenderer bev(m, cfg);
  EXPECT_EQ(bev.frame_bytes(), size_t(8 * 40 * 30));
}

TEST(Bev, BadConfigThrows) {
  const RoadMap m = two_way_road();
  BevConfig cfg;
  cfg.metres_per_pixel = 0;
  EXPECT_THROW(BevRenderer(m, cfg), Error);
  cfg = BevConfig{};
  cfg.static_supersample = 0;
  EXPECT_THROW(BevRenderer(m, cfg), Error);
}

// Axis-aligned case worked out by hand: a 4 x 2 m box 10 m ahead and 3.5 m left covers
// forward [8, 12], left [2.5, 4.5]; with the ego at row 48, col 32 and 0.5 m/px that is the
// pixel centres of rows 24..31 and columns 23..26.
TEST(Bev, VehicleBoxAxisAlignedByHand) {
  const RoadMap m = two_way_road();
  BevRenderer bev(m, BevConfig{});
  for (double heading : {0.0, M_PI / 2}) {
    BevScene s;
    s.ego = {{3.0, 0.4}, heading};
    s.vehicles.push_back({ahead_left(s.ego, 10, 3.5), heading, 4, 2});
    const Frame f = render(bev, s);
    for (int r = 0; r < 64; ++r)
      for (int c = 0; c < 64; ++c) {
        const bool in = r >= 24 && r <= 31 && c >= 23 && c <= 26;
        EXPECT_EQ(f.at(kBevVehicles, r, c), in ? 255 : 0)
            << "heading " << heading << " pixel " << r << "," << c;
      }
  }
}

TEST(Bev, VehicleBoxesRotatedMatchPixelCentres) {
  const RoadMap m = two_way_road();
  BevRenderer bev(m, BevConfig{});
  for (double heading : {0.0, M_PI / 2, 0.7, -2.3}) {
    BevScene s;
    s.ego = {{1.3, -0.45}, heading};
    s.vehicles.push_back({ahead_left(s.ego, 10.1, 3.37), heading + 0.4, 4, 2});
    s.vehicles.push_back({ahead_left(s.ego, -3.2, -4.1), heading - 1.1, 4.6, 1.9});
    // Partly outside the image: must be clipped, not wrapped or dropped.
    s.vehicles.push_back({ahead_left(s.ego, 5.05, 15.43), heading + 0.2, 4, 3});
    const Frame f = render(bev, s);
    expect_exact_boxes(f, kBevVehicles, s.ego, s.vehicles);
    // The ego itself is never drawn.
    EXPECT_EQ(f.at(kBevVehicles, 48, 32), 0);
  }
}

TEST(Bev, VehicleOutsideViewIsNotDrawn) {
  const RoadMap m = two_way_road();
  BevRenderer bev(m, BevConfig{});
  BevScene s;
  s.ego = {{0, 0}, 0.3};
  s.vehicles.push_back({ahead_left(s.ego, -20, 0), 0.3, 4, 2});   // behind (view: 8 m)
  s.vehicles.push_back({ahead_left(s.ego, 0, 40), 0.3, 4, 2});    // far left
  s.vehicles.push_back({ahead_left(s.ego, 1e9, -1e9), 0.3, 4, 2}); // absurdly far
  const Frame f = render(bev, s);
  for (int r = 0; r < 64; ++r)
    for (int c = 0; c < 64; ++c) ASSERT_EQ(f.at(kBevVehicles, r, c), 0);
}

// A 0.5 m pedestrian is grown to 2 x 2 px: centred 5.1 m ahead, 2.3 m left it sits at
// continuous (row, col) = (37.8, 27.4), so it covers centres within 1 px: rows 37-38,
// columns 26-27.
TEST(Bev, PedestrianLandsAtExpectedPixels) {
  const RoadMap m = two_way_road();
  BevRenderer bev(m, BevConfig{});
  BevScene s;
  s.ego = {{-7, 0.2}, 0};
  s.pedestrians.push_back({ahead_left(s.ego, 5.1, 2.3), 0.0, 0.5, 0.5});
  const Frame f = render(bev, s);
  int count = 0;
  for (int r = 0; r < 64; ++r)
    for (int c = 0; c < 64; ++c) {
      const bool in = (r == 37 || r == 38) && (c == 26 || c == 27);
      EXPECT_EQ(f.at(kBevPedestrians, r, c), in ? 255 : 0) << r << "," << c;
      count += f.at(kBevVehicles, r, c) != 0;
    }
  EXPECT_EQ(count, 0);
}

// A stop line across the ego's lane 6 m ahead: row 36 +- 1 px (rows 35, 36), columns over
// left in [-1.6, 1.6] m, i.e. continuous columns [28.8, 35.2] -> 29..34.
TEST(Bev, StopLineInItsChannel) {
  const RoadMap m = two_way_road();
  BevRenderer bev(m, BevConfig{});
  BevScene s;
  s.ego = {{0, 0}, 0};
  s.stop_lines.push_back({{6, 1.6}, {6, -1.6}, kBevLightRed});
  const Frame f = render(bev, s);
  for (int r = 0; r < 64; ++r)
    for (int c = 0; c < 64; ++c) {
      const bool in = (r == 35 || r == 36) && c >= 29 && c <= 34;
      EXPECT_EQ(f.at(kBevLightRed, r, c), in ? 255 : 0) << r << "," << c;
      EXPECT_EQ(f.at(kBevLightGreen, r, c), 0);
      EXPECT_EQ(f.at(kBevLightYield, r, c), 0);
    }
  s.stop_lines[0].channel = kBevVehicles;
  std::vector<uint8_t> buf(bev.frame_bytes());
  EXPECT_THROW(bev.render(s, buf.data()), Error);
}

TEST(Bev, DrivableUnderEgoAndEmptyFarOffRoad) {
  const RoadMap m = two_way_road();
  BevRenderer bev(m, BevConfig{});
  BevScene s;
  s.ego = {{12.3, 0.1}, 0.7};
  Frame f = render(bev, s);
  EXPECT_EQ(f.at(kBevDrivable, 48, 32), 255);

  s.ego = {{0, 50}, 0.7};  // the view reaches < 30 m; the road is 45 m away
  f = render(bev, s);
  for (int ch : {kBevDrivable, kBevMarkings, kBevRoute})
    for (int r = 0; r < 64; ++r)
      for (int c = 0; c < 64; ++c) ASSERT_EQ(f.at(ch, r, c), 0) << ch;

  s.ego = {{5000, -3000}, 1.1};  // outside the static raster altogether
  f = render(bev, s);
  for (int r = 0; r < 64; ++r)
    for (int c = 0; c < 64; ++c) ASSERT_EQ(f.at(kBevDrivable, r, c), 0);
}

// Lane centre lines are at known distances, so drivable pixels can be checked against the
// distance of each pixel centre to them (half a raster pixel diagonal of tolerance).
TEST(Bev, DrivableMatchesLaneGeometryAtAnyHeading) {
  const RoadMap m = two_way_road();
  BevRenderer bev(m, BevConfig{});
  for (double heading : {0.0, 0.7, 2.0}) {
    BevScene s;
    s.ego = {{0.37, 1.1}, heading};
    const Frame f = render(bev, s);
    for (int r = 0; r < 64; ++r)
      for (int c = 0; c < 64; ++c) {
        const Vec2 p = pixel_centre(f.cfg, s.ego, r, c);
        if (p.y > -1.4 && p.y < 4.6) {
          EXPECT_EQ(f.at(kBevDrivable, r, c), 255) << r << "," << c;
        }
        if (p.y < -1.8 || p.y > 5.0) {
          EXPECT_EQ(f.at(kBevDrivable, r, c), 0) << r << "," << c;
        }
      }
  }
}

// A 90-degree bend: the wedge outside the corner, beyond both segments' rectangles, must be
// filled too (no notch in the lane at turns).
TEST(Bev, BendHasNoGap) {
  RoadMap m;
  m.add(make_lane("B_0", {{0, 0}, {50, 0}, {50, 50}}));
  BevRenderer bev(m, BevConfig{});
  BevScene s;
  s.ego = {{45.2, 0.3}, 0.35};
  const Frame f = render(bev, s);
  int wedge = 0;
  for (int r = 0; r < 64; ++r)
    for (int c = 0; c < 64; ++c) {
      const Vec2 p = pixel_centre(f.cfg, s.ego, r, c);
      if ((p - Vec2{50, 0}).norm() < 1.4) {
        EXPECT_EQ(f.at(kBevDrivable, r, c), 255) << r << "," << c;
        wedge += p.x > 50 && p.y < 0;
      }
    }
  EXPECT_GT(wedge, 0);
}

// Facing north, the left of the image is west. Also: internal lanes are drivable, sidewalks
// are not, and internal lanes carry no markings.
TEST(Bev, HeadingNorthLeftLaneOnLeftHalf) {
  RoadMap m;
  m.add(make_lane("N_0", {{0, -100}, {0, 100}}));
  m.add(make_lane("L_0", {{-10, 100}, {-10, -100}}));
  m.add(make_lane(":J_0_0", {{6, -100}, {6, 100}}, LaneKind::Driving, true));
  m.add(make_lane("S_0", {{12, -100}, {12, 100}}, LaneKind::Sidewalk));
  BevRenderer bev(m, BevConfig{});
  BevScene s;
  s.ego = {{0, 0}, M_PI / 2};
  const Frame f = render(bev, s);
  EXPECT_EQ(f.at(kBevDrivable, 48, 32), 255);
  // L_0 is 10 m left: continuous columns [8.8, 15.2].
  for (int r = 0; r < 64; ++r) {
    for (int c = 10; c <= 13; ++c) EXPECT_EQ(f.at(kBevDrivable, r, c), 255) << r << "," << c;
    for (int c = 17; c <= 26; ++c) EXPECT_EQ(f.at(kBevDrivable, r, c), 0) << r << "," << c;
    // Internal lane 6 m right: columns [40.8, 47.2]; no markings of its own.
    for (int c = 42; c <= 46; ++c) EXPECT_EQ(f.at(kBevDrivable, r, c), 255) << r << "," << c;
    for (int c = 39; c < 64; ++c) EXPECT_EQ(f.at(kBevMarkings, r, c), 0) << r << "," << c;
    // Sidewalk 12 m right: columns [52.8, 59.2], not drivable.
    for (int c = 50; c < 64; ++c) EXPECT_EQ(f.at(kBevDrivable, r, c), 0) << r << "," << c;
  }
}

// Facing east on the two-lane edge with the ego on E_0 (y = -1.6): the divider (y = 0) is
// 1.6 m left, continuous column 28.8; the solid border (y = -3.2) is 1.6 m right, column
// 35.2. Rows run along the road.
TEST(Bev, DashedDividerAndSolidBorder) {
  const RoadMap m = two_lane_edge();
  BevRenderer bev(m, BevConfig{});
  BevScene s;
  s.ego = {{0.2, -1.6}, 0};
  const Frame f = render(bev, s);
  auto marked = [&](int r, int c0, int c1) {
    for (int c = c0; c <= c1; ++c)
      if (f.at(kBevMarkings, r, c)) return true;
    return false;
  };
  int divider_rows = 0, transitions = 0;
  for (int r = 0; r < 64; ++r) {
    EXPECT_TRUE(marked(r, 34, 37)) << "gap in solid border at row " << r;
    EXPECT_FALSE(marked(r, 31, 33)) << "marking inside the lane at row " << r;
    divider_rows += marked(r, 27, 30);
    if (r > 0) transitions += marked(r, 27, 30) != marked(r - 1, 27, 30);
  }
  // 3 m dashes, 3 m gaps: about half of the 32 m visible.
  EXPECT_GE(divider_rows, 20);
  EXPECT_LE(divider_rows, 44);
  EXPECT_GE(transitions, 4);
}

// The solid border must stay connected at any pose: every image row that crosses it has a
// marking pixel within 2 columns of the crossing.
TEST(Bev, SolidBorderHasNoGapsAtAnyPose) {
  const RoadMap m = two_lane_edge();
  BevConfig cfg;
  BevRenderer bev(m, cfg);
  for (double heading : {0.0, 0.3, 0.7, M_PI / 4, -0.2}) {
    for (int k = 0; k < 8; ++k) {
      BevScene s;
      s.ego = {{0.13 * k, -1.6 + 0.07 * k}, heading};
      const Frame f = render(bev, s);
      for (int r = 0; r < 64; ++r) {
        // The border y = -3.2 crosses row r at the column where the (affine) y of the pixel
        // centres along the row reaches -3.2.
        const double y0 = pixel_centre(cfg, s.ego, r, 0).y;
        const double y1 = pixel_centre(cfg, s.ego, r, 63).y;
        const double col = (y0 + 3.2) / (y0 - y1) * 63;
        if (col < 3 || col > 60) continue;
        bool hit = false;
        for (int c = int(std::lround(col)) - 2; c <= int(std::lround(col)) + 2; ++c)
          hit = hit || f.at(kBevMarkings, r, c);
        EXPECT_TRUE(hit) << "heading " << heading << " k " << k << " row " << r;
      }
    }
  }
}

// The opposite lanes of a two-way road share the centre line (y = 0); drawing it from either
// side alone must give the same dashes. The right borders are suppressed, and a sidewalk
// (never drawn) gives both maps the same bounds, hence the same static raster grid.
TEST(Bev, CentreLineDashesIndependentOfDirection) {
  RoadMap east, west;
  east.add(make_lane("E_0", {{-100, -1.6}, {100, -1.6}}, LaneKind::Driving, false, false, true));
  west.add(make_lane("W_0", {{100, 1.6}, {-100, 1.6}}, LaneKind::Driving, false, false, true));
  for (RoadMap* m : {&east, &west}) m->add(make_lane("S_0", {{-100, -9}, {100, 9}}, LaneKind::Sidewalk));
  BevRenderer be(east, BevConfig{}), bw(west, BevConfig{});
  BevScene s;
  s.ego = {{0.4, 0.1}, 0.25};
  const Frame fe = render(be, s), fw = render(bw, s);
  int painted = 0;
  for (int r = 0; r < 64; ++r)
    for (int c = 0; c < 64; ++c) {
      EXPECT_EQ(fe.at(kBevMarkings, r, c), fw.at(kBevMarkings, r, c)) << r << "," << c;
      painted += fe.at(kBevMarkings, r, c) != 0;
    }
  EXPECT_GT(painted, 0);
}

TEST(Bev, RouteCoincidesWithLane) {
  const RoadMap m = two_way_road();
  BevRenderer bev(m, BevConfig{});
  BevScene s;
  s.ego = {{0.3, 0.2}, 0.7};
  Frame f = render(bev, s);
  for (size_t i = 0; i < size_t(64 * 64); ++i)
    ASSERT_EQ(f.data[kBevRoute * 64 * 64 + i], 0) << "route drawn before set_route";

  bev.set_route({"E_0"});
  f = render(bev, s);
  int route_pixels = 0;
  for (int r = 0; r < 64; ++r)
    for (int c = 0; c < 64; ++c) {
      const Vec2 p = pixel_centre(f.cfg, s.ego, r, c);
      if (std::abs(p.y) < 1.4) {
        EXPECT_EQ(f.at(kBevRoute, r, c), 255) << r << "," << c;
      }
      if (std::abs(p.y) > 1.8) {
        EXPECT_EQ(f.at(kBevRoute, r, c), 0) << r << "," << c;
      }
      if (f.at(kBevRoute, r, c)) {
        EXPECT_EQ(f.at(kBevDrivable, r, c), 255);
      }
      route_pixels += f.at(kBevRoute, r, c) != 0;
    }
  EXPECT_GT(route_pixels, 100);

  // A bad id throws, names the id and leaves the previous route in place.
  try {
    bev.set_route({"W_0", "no_such_lane"});
    FAIL() << "expected cd::Error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("no_such_lane"), std::string::npos);
  }
  EXPECT_EQ(render(bev, s).data, f.data);

  // A new route replaces the old one.
  bev.set_route({"W_0"});
  f = render(bev, s);
  EXPECT_EQ(f.at(kBevRoute, 48, 32), 0);
  const Vec2 w = {0.3, 3.2};  // on W_0
  bool found = false;
  for (int r = 0; r < 64 && !found; ++r)
    for (int c = 0; c < 64 && !found; ++c)
      if ((pixel_centre(f.cfg, s.ego, r, c) - w).norm() < 0.4) {
        EXPECT_EQ(f.at(kBevRoute, r, c), 255);
        found = true;
      }
  EXPECT_TRUE(found);
}

TEST(Bev, RenderIsDeterministicAndOverwritesTheBuffer) {
  const RoadMap m = two_lane_edge();
  BevRenderer a(m, BevConfig{}), b(m, BevConfig{});
  a.set_route({"E_0"});
  b.set_route({"E_0"});
  BevScene s;
  s.ego = {{3.3, -1.2}, 0.41};
  s.vehicles.push_back({ahead_left(s.ego, 8, 0.2), 0.5, 4.5, 1.8});
  s.pedestrians.push_back({ahead_left(s.ego, 4, -5), 0, 0.5, 0.5});
  s.stop_lines.push_back({{10, -3.2}, {10, 0}, kBevLightYield});
  std::vector<uint8_t> x(a.frame_bytes(), 0), y(a.frame_bytes(), 0xAB), z(b.frame_bytes(), 7);
  a.render(s, x.data());
  a.render(s, y.data());
  b.render(s, z.data());
  EXPECT_EQ(x, y);
  EXPECT_EQ(x, z);
  for (uint8_t v : x) ASSERT_TRUE(v == 0 || v == 255);
}

std::string read_all(const std::filesystem::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

TEST(Bev, WritePng) {
  const RoadMap m = two_lane_edge();
  BevRenderer bev(m, BevConfig{});
  bev.set_route({"E_0"});
  BevScene s;
  s.ego = {{0, -1.6}, 0.2};
  s.vehicles.push_back({ahead_left(s.ego, 8, 0), 0.2, 4.5, 1.8});
  const Frame f = render(bev, s);

  const auto dir = std::filesystem::path(testing::TempDir()) /
                   ("bev_png_" + std::to_string(::testing::UnitTest::GetInstance()->random_seed()));
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  const auto p1 = dir / "a.png", p2 = dir / "b.png";
  write_bev_png(p1.string(), f.data.data(), kBevChannelCount, 64, 64, 4);
  write_bev_png(p2.string(), f.data.data(), kBevChannelCount, 64, 64, 4);
  const std::string a = read_all(p1), b = read_all(p2);
  ASSERT_GE(a.size(), 8u);
  EXPECT_EQ(a.substr(0, 8), std::string("\x89PNG\r\n\x1a\n", 8));
  EXPECT_EQ(a, b);
  // Only the two finished files: no temporary left behind.
  EXPECT_EQ(std::distance(std::filesystem::directory_iterator(dir),
                          std::filesystem::directory_iterator()),
            2);

  EXPECT_THROW(write_bev_png((dir / "missing_dir" / "x.png").string(), f.data.data(),
                             kBevChannelCount, 64, 64, 4),
               IoError);
  EXPECT_THROW(write_bev_png(p1.string(), f.data.data(), kBevChannelCount + 1, 64, 64, 4), Error);
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace cd
