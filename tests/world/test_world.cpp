// The driving world: stepping, the ego model, collisions, red lights, the BEV in the live
// world, ground truth and errors.
//
// libsumo runs one simulation per process and ctest runs every TEST in its own process, so
// each TEST below creates at most one World at a time.
#include "world/world.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <string>
#include <vector>

#include "app/settings.hpp"
#include "core/error.hpp"
#include "expert/autopilot.hpp"
#include "sense/bev.hpp"
#include "../support/test_support.hpp"
#include "world/collision.hpp"
#include "world/ego_model.hpp"

namespace cd {
namespace {

using test::TempDir;

constexpr Control kThrottle{1.0, 0.0};
constexpr Control kBrake{0.0, 1.0};

// The test config (town-a, short warm-up, short routes) read back through load_settings.
Settings test_settings(const std::string& traffic = "empty") {
  TempDir dir("cdtest-world");
  return load_settings(test::write_test_config(dir, traffic));
}

bool contains(const std::vector<std::string>& v, const std::string& s) {
  return std::find(v.begin(), v.end(), s) != v.end();
}

// Largest distance of a lane's shape points from the chord between its ends.
double bend_of(const LaneGeom& g) {
  Vec2 a = g.shape.front(), b = g.shape.back(), d = b - a;
  double len = d.norm(), worst = 0;
  for (const Vec2& p : g.shape) worst = std::max(worst, std::abs((p - a).cross(d)) / len);
  return worst;
}

// Town-a's grid edges are named after their two junctions, a letter and a digit each ("B2B3");
// border stubs have longer names ("left1A1").
bool is_grid_edge(const std::string& e) {
  return e.size() == 4 && std::isupper(static_cast<unsigned char>(e[0])) &&
         std::isdigit(static_cast<unsigned char>(e[1])) &&
         std::isupper(static_cast<unsigned char>(e[2])) &&
         std::isdigit(static_cast<unsigned char>(e[3]));
}

// Resets `w` on the first task (seeds 0, 1, ...) whose first route lane is a straight normal
// Adds a pedestrian standing at `at` and steps twice with the ego braking so that it is there.
// Returns its id, or "" (with a test failure) when SUMO did not put it there.
std::string add_pedestrian(World& w, Vec2 at);

// lane with at least `room` metres ahead of the ego's front (and, if asked, on a grid edge).
// Fails the test when none is found.
Task reset_with_room(World& w, double room, bool grid_edge = false) {
  for (uint64_t seed = 0; seed < 40; ++seed) {
    Task t = w.sample_task(seed, 100, 200);
    w.reset(t);
    if (w.route_lanes().empty()) continue;
    const LaneGeom* g = w.map().find(w.route_lanes().front());
    if (g && !g->internal && g->id == w.ego().lane && bend_of(*g) < 0.05 &&
        g->length - w.ego().lane_pos >= room && (!grid_edge || is_grid_edge(g->edge)))
      return t;
  }
  ADD_FAILURE() << "no task among seeds 0..39 starts with " << room << " m of straight lane";
  return {};
}

const Actor* find_actor(const World& w, const std::string& id) {
  for (const Actor& a : w.actors())
    if (a.id == id) return &a;
  return nullptr;
}

// Adds a scripted vehicle and steps once with the ego braking, so that it is in the world.
// Returns its id, or "" (with a test failure) when SUMO did not insert it.
std::string add_vehicle(World& w, const std::string& lane, double pos, double speed) {
  std::string id = w.add_scripted_vehicle(lane, pos, speed);
  StepResult r = w.step(kBrake);
  EXPECT_EQ(r.outcome, Outcome::Running) << "collided_with=" << r.collided_with;
  if (!find_actor(w, id)) {
    ADD_FAILURE() << "scripted vehicle " << id << " on " << lane << " at " << pos
                  << " is not in the world after one step";
    return "";
  }
  return id;
}

std::string add_pedestrian(World& w, Vec2 at) {
  const LaneGeom* lane = w.map().find(w.ego().lane);
  const std::string id = w.add_scripted_pedestrian(lane->edge, 0.0);
  EXPECT_EQ(w.step(kBrake).outcome, Outcome::Running);
  w.place_pedestrian(id, at);
  EXPECT_EQ(w.step(kBrake).outcome, Outcome::Running);
  for (const Actor& a : w.actors())
    if (a.id == id) {
      EXPECT_TRUE(a.pedestrian);
      EXPECT_LT((a.box.center - at).norm(), 1.0) << "the pedestrian is not where it was put";
      return id;
    }
  ADD_FAILURE() << "scripted pedestrian " << id << " is not in the world after two steps";
  return "";
}

// Unit vectors ahead and to the left of the ego.
Vec2 fwd(const Pose2& p) { return {std::cos(p.heading), std::sin(p.heading)}; }
Vec2 lft(const Pose2& p) { return {-std::sin(p.heading), std::cos(p.heading)}; }

// Bumper-to-bumper gap between the ego and a box straight ahead of it.
double gap_to(const World& w, const Box& b) {
  const Pose2& e = w.ego().pose;
  double ahead = (b.center - e.pos).dot(fwd(e));
  return ahead - b.length / 2 - w.settings().ego.length / 2;
}

// Distance the ego needs to stop from v at full brake, stepping the ego model like the world.
double stopping_distance(const EgoModel& m, double v, double dt) {
  double d = 0;
  for (int i = 0; i < 10000 && v > 0; ++i) {
    v = m.next_speed(kBrake, v, dt);
    d += v * dt;
  }
  return d;
}

// ---------------------------------------------------------------------------------------------
// Reset and stepping

TEST(WorldStep, ResetStartsStoppedAndFullThrottleAccelerates) {
  CD_NEEDS_SUMO();
  Settings s = test_settings();
  World w(s);
  Task task = w.sample_task(0, 100, 200);
  ASSERT_FALSE(task.route.empty());
  EXPECT_GE(task.route_length, 100.0 - 1e-6);
  EXPECT_LE(task.route_length, 200.0 + 1e-6);
  w.reset(task);

  EXPECT_EQ(w.ego().speed, 0.0);
  EXPECT_EQ(w.ego().time, 0.0);
  EXPECT_EQ(w.time(), 0.0);
  EXPECT_NEAR(w.ego().progress, 0.0, 1e-9);
  EXPECT_EQ(w.counters().distance, 0.0);
  EXPECT_EQ(w.counters().red_light_violations, 0);
  ASSERT_FALSE(w.route_lanes().empty());
  EXPECT_EQ(w.route_lanes().front(), w.ego().lane);
  const std::vector<std::string> route_lanes = w.route_lanes();

  const double dt = s.world.dt;
  double prev_speed = 0, prev_progress = 0, prev_distance = 0;
  for (int i = 0; i < 30; ++i) {
    StepResult r = w.step(kThrottle);
    ASSERT_EQ(r.outcome, Outcome::Running) << "step " << i << " collided_with=" << r.collided_with;
    const EgoState& e = w.ego();
    EXPECT_GT(e.speed, prev_speed) << "step " << i;
    EXPECT_LE(e.speed, s.ego.max_speed) << "step " << i;
    // The speed is the ego model's, not SUMO's own driver.
    EXPECT_NEAR(e.speed, w.ego_model().next_speed(kThrottle, prev_speed, dt), 1e-3) << "step " << i;
    EXPECT_NEAR(e.time, (i + 1) * dt, 1e-6) << "step " << i;
    EXPECT_GT(e.progress, prev_progress) << "step " << i;
    EXPECT_GT(w.counters().distance, prev_distance) << "step " << i;
    EXPECT_NEAR(w.counters().distance, e.progress, 0.05) << "step " << i;
    EXPECT_TRUE(contains(route_lanes, e.lane)) << "step " << i << ": ego on " << e.lane
                                               << ", which is not a route lane";
    prev_speed = e.speed;
    prev_progress = e.progress;
    prev_distance = w.counters().distance;
  }
  // 30 steps of full throttle from standstill cover about a*t^2/2 with a <= max_accel.
  double t = 30 * dt;
  EXPECT_GT(prev_progress, 0.5 * 0.5 * s.ego.max_accel * t * t);
  EXPECT_LT(prev_progress, 0.5 * s.ego.max_accel * t * t + 0.5);
}

TEST(WorldStep, SpeedNeverExceedsEgoMaxSpeed) {
  CD_NEEDS_SUMO();
  Settings s = test_settings();
  s.ego.max_speed = 6.0;
  World w(s);
  w.reset(w.sample_task(1, 100, 200));
  double top = 0;
  StepResult r;
  std::string prev_lane = w.ego().lane;
  for (int i = 0; i < 200 && r.outcome == Outcome::Running; ++i) {
    r = w.step(kThrottle);
    ASSERT_NE(r.outcome, Outcome::Collision) << r.collided_with;
    EXPECT_LE(w.ego().speed, 6.0 + 1e-9) << "step " << i;
    top = std::max(top, w.ego().speed);
  }
  EXPECT_GT(top, 5.0) << "the ego never got near its top speed";
}

TEST(WorldStep, StepAfterTheEndThrowsAndResetRestarts) {
  CD_NEEDS_SUMO();
  Settings s = test_settings();
  World w(s);
  Task task = w.sample_task(0, 100, 200);
  w.reset(task);
  StepResult r;
  int steps = 0;
  while (r.outcome == Outcome::Running && steps < 2000) {
    r = w.step(kThrottle);
    ++steps;
  }
  ASSERT_EQ(r.outcome, Outcome::Success) << "full throttle on an empty town should reach the goal";
  EXPECT_NEAR(w.counters().distance, task.route_length, 15.0);
  EXPECT_THROW(w.step(kThrottle), SimError);
  w.reset(task);
  EXPECT_EQ(w.ego().speed, 0.0);
  EXPECT_EQ(w.counters().distance, 0.0);
  EXPECT_EQ(w.step(kThrottle).outcome, Outcome::Running);
}

TEST(WorldStep, SecondWorldThrowsWhileFirstIsAliveThenNewWorldWorks) {
  CD_NEEDS_SUMO();
  Settings s = test_settings();
  {
    World first(s);
    EXPECT_THROW({ World second(s); }, SimError);
    // The failed construction must not have closed the first simulation.
    first.reset(first.sample_task(0, 100, 200));
    EXPECT_EQ(first.step(kThrottle).outcome, Outcome::Running);
  }
  World again(s);
  again.reset(again.sample_task(2, 100, 200));
  EXPECT_EQ(again.step(kThrottle).outcome, Outcome::Running);
  EXPECT_GT(again.ego().speed, 0.0);
}

// ---------------------------------------------------------------------------------------------
// Ego vehicle model (pure)

TEST(EgoModel, HandComputedAccelerations) {
  EgoSettings es;  // defaults: max_accel 3.5, max_decel 8, max_speed 20, rolling 0.1, drag 8e-4
  EgoModel m(es);
  EXPECT_DOUBLE_EQ(m.acceleration({1, 0}, 0), 3.5);
  EXPECT_DOUBLE_EQ(m.acceleration({0, 0}, 0), 0.0);  // no resistance at standstill
  EXPECT_NEAR(m.acceleration({1, 0}, 10), 3.5 * 0.5 - 0.1 - 0.0008 * 100, 1e-12);
  EXPECT_NEAR(m.acceleration({0, 1}, 10), -8.0 - 0.1 - 0.0008 * 100, 1e-12);
  EXPECT_NEAR(m.acceleration({0.5, 0}, 20), -0.1 - 0.0008 * 400, 1e-12);
  EXPECT_NEAR(m.acceleration({0, 0.25}, 5), -2.0 - 0.1 - 0.0008 * 25, 1e-12);
  // Controls outside [0,1] are clamped.
  EXPECT_DOUBLE_EQ(m.acceleration({2.0, 0}, 0), 3.5);
  EXPECT_DOUBLE_EQ(m.acceleration({-1.0, 0}, 0), 0.0);
  EXPECT_NEAR(m.acceleration({0, 5.0}, 10), m.acceleration({0, 1}, 10), 1e-12);
}

TEST(EgoModel, AccelerationStaysWithinLimits) {
  EgoSettings es;
  EgoModel m(es);
  for (double v = 0; v <= es.max_speed + 1e-9; v += 0.5) {
    const double resist = v > 0 ? es.rolling + es.drag * v * v : 0.0;
    for (double t = -0.5; t <= 1.5; t += 0.125) {
      for (double b = -0.5; b <= 1.5; b += 0.125) {
        double a = m.acceleration({t, b}, v);
        EXPECT_LE(a, es.max_accel + 1e-12) << "t=" << t << " b=" << b << " v=" << v;
        EXPECT_GE(a, -es.max_decel - resist - 1e-12) << "t=" << t << " b=" << b << " v=" << v;
      }
    }
  }
}

TEST(EgoModel, NextSpeedIsClampedToZeroAndMaxSpeed) {
  EgoSettings es;
  EgoModel m(es);
  EXPECT_EQ(m.next_speed(kBrake, 0.5, 0.1), 0.0);  // 0.5 - 0.81 < 0: no reverse
  EXPECT_EQ(m.next_speed(kBrake, 0.0, 0.1), 0.0);
  EXPECT_EQ(m.next_speed({0, 0}, 0.0, 0.1), 0.0);  // standing still stays still
  EXPECT_NEAR(m.next_speed(kThrottle, 0.0, 0.1), 0.35, 1e-12);
  EXPECT_EQ(m.next_speed(kThrottle, 25.0, 0.1), es.max_speed);  // above the limit: clamped

  EgoSettings frictionless = es;
  frictionless.rolling = 0;
  frictionless.drag = 0;
  EgoModel f(frictionless);
  EXPECT_EQ(f.next_speed(kThrottle, 19.0, 10.0), es.max_speed);  // 19 + 0.175 * 10 > 20

  for (double v = 0; v <= es.max_speed; v += 0.25) {
    for (double t = 0; t <= 1.0; t += 0.25) {
      for (double b = 0; b <= 1.0; b += 0.25) {
        for (double dt : {0.05, 0.1, 1.0, 5.0}) {
          double n = m.next_speed({t, b}, v, dt);
          EXPECT_GE(n, 0.0);
          EXPECT_LE(n, es.max_speed);
        }
      }
    }
  }
}

TEST(EgoModel, ControlForReproducesTheAccelerationWithinLimits) {
  EgoSettings es;
  EgoModel m(es);
  // Hand-computed: at 10 m/s resistance is 0.18, full throttle gives 1.75 before it.
  Control c = m.control_for(1.57, 10);
  EXPECT_NEAR(c.throttle, 1.0, 1e-9);
  EXPECT_EQ(c.brake, 0.0);
  c = m.control_for(-4.0, 10);
  EXPECT_EQ(c.throttle, 0.0);
  EXPECT_NEAR(c.brake, (4.0 - 0.18) / 8.0, 1e-12);
  EXPECT_NEAR(m.acceleration(c, 10), -4.0, 1e-12);
  c = m.control_for(1.75, 0);
  EXPECT_NEAR(c.throttle, 0.5, 1e-12);
  EXPECT_EQ(c.brake, 0.0);
  // Beyond the limits: saturated at full throttle or full brake.
  c = m.control_for(10.0, 0);
  EXPECT_EQ(c.throttle, 1.0);
  EXPECT_NEAR(m.acceleration(c, 0), es.max_accel, 1e-12);
  c = m.control_for(-20.0, 5);
  EXPECT_EQ(c.brake, 1.0);
  EXPECT_NEAR(m.acceleration(c, 5), -8.0 - 0.1 - 0.0008 * 25, 1e-12);

  for (double v = 0; v <= es.max_speed - 1; v += 0.5) {
    const double lo = m.acceleration(kBrake, v), hi = m.acceleration(kThrottle, v);
    for (double a = -10; a <= 5; a += 0.25) {
      Control k = m.control_for(a, v);
      EXPECT_GE(k.throttle, 0.0);
      EXPECT_LE(k.throttle, 1.0);
      EXPECT_GE(k.brake, 0.0);
      EXPECT_LE(k.brake, 1.0);
      EXPECT_TRUE(k.throttle == 0.0 || k.brake == 0.0) << "both pedals at a=" << a << " v=" << v;
      EXPECT_NEAR(m.acceleration(k, v), std::clamp(a, lo, hi), 1e-9) << "a=" << a << " v=" << v;
    }
  }
}

// ---------------------------------------------------------------------------------------------
// Oriented boxes (pure)

TEST(BoxesOverlap, AxisAlignedCases) {
  const Box a{{0, 0}, 0, 4, 2};
  EXPECT_TRUE(boxes_overlap(a, a));
  EXPECT_TRUE(boxes_overlap(a, Box{{3.9, 0}, 0, 4, 2}));     // 0.1 m overlap lengthwise
  EXPECT_FALSE(boxes_overlap(a, Box{{4.0, 0}, 0, 4, 2}));    // touching: not a collision
  EXPECT_FALSE(boxes_overlap(a, Box{{4.1, 0}, 0, 4, 2}));    // separated by 0.1 m
  EXPECT_FALSE(boxes_overlap(a, Box{{-4.1, 0}, 0, 4, 2}));
  EXPECT_TRUE(boxes_overlap(a, Box{{0, 1.9}, 0, 4, 2}));     // 0.1 m overlap sideways
  EXPECT_FALSE(boxes_overlap(a, Box{{0, 2.1}, 0, 4, 2}));    // side by side, 0.1 m apart
  EXPECT_FALSE(boxes_overlap(a, Box{{0, -2.1}, 0, 4, 2}));
  EXPECT_TRUE(boxes_overlap(a, Box{{0, 0}, 0, 1, 0.5}));     // one inside the other
  // A box heading the other way is the same rectangle.
  EXPECT_FALSE(boxes_overlap(a, Box{{4.1, 0}, M_PI, 4, 2}));
  EXPECT_TRUE(boxes_overlap(a, Box{{3.9, 0}, M_PI, 4, 2}));
  // Crossing at right angles (a T): 4x2 across the end of the other.
  EXPECT_TRUE(boxes_overlap(a, Box{{2.9, 0}, M_PI / 2, 4, 2}));
  EXPECT_FALSE(boxes_overlap(a, Box{{3.1, 0}, M_PI / 2, 4, 2}));
}

TEST(BoxesOverlap, RotatedFortyFiveDegrees) {
  const Box a{{0, 0}, 0, 2, 2};
  // A 2x2 square turned 45 deg reaches sqrt(2) from its centre along the x axis.
  EXPECT_TRUE(boxes_overlap(a, Box{{2.3, 0}, M_PI / 4, 2, 2}));   // corner 0.114 m inside
  EXPECT_FALSE(boxes_overlap(a, Box{{2.5, 0}, M_PI / 4, 2, 2}));  // corner 0.086 m outside
  // Diagonal neighbours: the projections on a's axes overlap, only the rotated box's own axis
  // separates them (a test on one box's axes alone would report a collision).
  EXPECT_FALSE(boxes_overlap(a, Box{{1.9, 1.9}, M_PI / 4, 2, 2}));
  EXPECT_TRUE(boxes_overlap(a, Box{{1.5, 1.5}, M_PI / 4, 2, 2}));
  // Two long thin boxes crossing as an X overlap; parallel diagonal ones 0.1 m apart do not.
  const Box d{{0, 0}, M_PI / 4, 10, 1};
  EXPECT_TRUE(boxes_overlap(d, Box{{0, 0}, -M_PI / 4, 10, 1}));
  const Vec2 normal{-std::sin(M_PI / 4), std::cos(M_PI / 4)};
  EXPECT_FALSE(boxes_overlap(d, Box{normal * 1.1, M_PI / 4, 10, 1}));
  EXPECT_TRUE(boxes_overlap(d, Box{normal * 0.9, M_PI / 4, 10, 1}));
}

TEST(CollisionStriker, TheOneClosingFasterStruck) {
  const Box ego{{0, 0}, 0, 4.5, 1.8};
  // A stopped car ahead: the moving ego struck it; a car running into the stopped ego's rear
  // struck the ego.
  EXPECT_TRUE(a_strikes(ego, 8.0, Box{{4.5, 0}, 0, 4.5, 1.8}, 0.0));
  EXPECT_FALSE(a_strikes(ego, 0.0, Box{{-4.5, 0}, 0, 4.5, 1.8}, 10.0));
  // A car crossing from the left into the ego's side while the ego creeps: the car struck.
  EXPECT_FALSE(a_strikes(ego, 1.0, Box{{0.5, 2.5}, -M_PI / 2, 4.5, 1.8}, 9.0));
  // The ego at speed into a pedestrian walking across its path: the ego struck.
  EXPECT_TRUE(a_strikes(ego, 10.0, Box{{3.0, 0.3}, M_PI / 2, 0.5, 0.5}, 1.3));
  // Head-on: the faster one.
  EXPECT_TRUE(a_strikes(ego, 12.0, Box{{4.6, 0}, M_PI, 4.5, 1.8}, 5.0));
  EXPECT_FALSE(a_strikes(ego, 5.0, Box{{4.6, 0}, M_PI, 4.5, 1.8}, 12.0));
}

TEST(BoxesOverlap, IsSymmetric) {
  std::vector<Box> boxes = {{{0, 0}, 0, 4, 2},           {{3.9, 0}, 0, 4, 2},
                            {{4.1, 0}, 0, 4, 2},         {{1.9, 1.9}, M_PI / 4, 2, 2},
                            {{1.5, 1.5}, M_PI / 4, 2, 2}, {{3.3, 0}, M_PI / 4, 2, 2},
                            {{0, 2.1}, 0.3, 4.5, 1.8},   {{2, 1}, -1.2, 5, 1.8}};
  for (const Box& p : boxes)
    for (const Box& q : boxes) EXPECT_EQ(boxes_overlap(p, q), boxes_overlap(q, p));
}

TEST(BoxesOverlap, BoxFromSumoFront) {
  // SUMO angle 90 = heading east: the centre is half a length west of the front bumper.
  Box east = box_from_front({10, 0}, 90.0, 4.0, 2.0);
  EXPECT_NEAR(east.center.x, 8.0, 1e-9);
  EXPECT_NEAR(east.center.y, 0.0, 1e-9);
  EXPECT_NEAR(east.heading, 0.0, 1e-9);
  EXPECT_EQ(east.length, 4.0);
  EXPECT_EQ(east.width, 2.0);
  // SUMO angle 0 = north.
  Box north = box_from_front({10, 0}, 0.0, 4.0, 2.0);
  EXPECT_NEAR(north.center.x, 10.0, 1e-9);
  EXPECT_NEAR(north.center.y, -2.0, 1e-9);
  EXPECT_NEAR(north.heading, M_PI / 2, 1e-9);
  // The front corners of the box are at the front bumper.
  auto c = box_corners(east);
  double max_x = -1e9;
  for (const Vec2& p : c) max_x = std::max(max_x, p.x);
  EXPECT_NEAR(max_x, 10.0, 1e-9);
}

// ---------------------------------------------------------------------------------------------
// Collisions in the live world

TEST(WorldCollision, FullThrottleIntoStoppedVehicleCollides) {
  CD_NEEDS_SUMO();
  World w(test_settings());
  ASSERT_FALSE(reset_with_room(w, 45).route.empty());
  const std::string lane = w.route_lanes().front();
  std::string id = add_vehicle(w, lane, w.ego().lane_pos + 25, 0.0);
  ASSERT_FALSE(id.empty());
  StepResult r;
  int steps = 0;
  for (; steps < 100 && r.outcome == Outcome::Running; ++steps) {
    r = w.step(kThrottle);
    if (r.outcome == Outcome::Running) {
      const Actor* a = find_actor(w, id);
      ASSERT_NE(a, nullptr);
      EXPECT_LT(a->speed, 0.01) << "the scripted vehicle should stay where it was put";
    }
  }
  ASSERT_EQ(r.outcome, Outcome::Collision) << "no collision after " << steps << " steps";
  EXPECT_EQ(r.collided_with, id);
  EXPECT_EQ(r.collision_kind, "vehicle");
  EXPECT_TRUE(r.ego_struck) << "the ego ran into a stopped car";
  // 20 m of gap at full throttle: about 3.4 s; never before the ego could get there.
  EXPECT_GT(steps, 20);
  EXPECT_THROW(w.step(kBrake), SimError);
}

TEST(WorldCollision, StoppedEgoRearEndedWasStruck) {
  CD_NEEDS_SUMO();
  World w(test_settings());
  ASSERT_FALSE(reset_with_room(w, 45).route.empty());
  const std::string lane = w.ego().lane;
  // Drive 22 m into the lane, then stop.
  const double start = w.ego().lane_pos;
  for (int i = 0; i < 100 && w.ego().lane_pos < start + 22; ++i)
    ASSERT_EQ(w.step(kThrottle).outcome, Outcome::Running);
  for (int i = 0; i < 100 && w.ego().speed > 0; ++i)
    ASSERT_EQ(w.step(kBrake).outcome, Outcome::Running);
  ASSERT_EQ(w.ego().lane, lane);
  ASSERT_EQ(w.ego().speed, 0.0);
  // A scripted car (it ignores safe speeds) stopped 15 m behind, then told to drive 10 m/s;
  // the ego keeps braking.
  std::string id = add_vehicle(w, lane, w.ego().lane_pos - 15, 0.0);
  ASSERT_FALSE(id.empty());
  w.set_vehicle_speed(id, 10.0);
  StepResult r;
  int steps = 0;
  for (; steps < 100 && r.outcome == Outcome::Running; ++steps) r = w.step(kBrake);
  ASSERT_EQ(r.outcome, Outcome::Collision) << "no collision after " << steps << " steps";
  EXPECT_EQ(r.collided_with, id);
  EXPECT_EQ(r.collision_kind, "vehicle");
  EXPECT_FALSE(r.ego_struck) << "a stopped ego hit from behind did not strike";
}

TEST(WorldCollision, FullThrottleIntoAPedestrianIsAPedestrianCollision) {
  CD_NEEDS_SUMO();
  World w(test_settings());
  ASSERT_FALSE(reset_with_room(w, 45).route.empty());
  const Pose2 e = w.ego().pose;
  const Vec2 at = e.pos + Vec2{std::cos(e.heading), std::sin(e.heading)} * 20.0;  // on its lane
  const std::string id = add_pedestrian(w, at);
  ASSERT_FALSE(id.empty());
  StepResult r;
  int steps = 0;
  for (; steps < 100 && r.outcome == Outcome::Running; ++steps) {
    w.place_pedestrian(id, at);  // it stands there (placed again each step)
    r = w.step(kThrottle);
  }
  ASSERT_EQ(r.outcome, Outcome::Collision) << "no collision after " << steps << " steps";
  EXPECT_EQ(r.collided_with, id);
  EXPECT_EQ(r.collision_kind, "pedestrian");
  EXPECT_TRUE(r.ego_struck) << "the ego ran into a standing pedestrian";
  EXPECT_GT(steps, 15) << "about 15 m of gap at full throttle take about 3 s";
}

TEST(WorldCollision, BrakingToAStopJustBehindIsNoCollision) {
  CD_NEEDS_SUMO();
  Settings s = test_settings();
  World w(s);
  ASSERT_FALSE(reset_with_room(w, 45).route.empty());
  const std::string lane = w.route_lanes().front();
  std::string id = add_vehicle(w, lane, w.ego().lane_pos + 25, 0.0);
  ASSERT_FALSE(id.empty());
  const double dt = s.world.dt;
  const EgoModel& m = w.ego_model();
  bool braking = false;
  for (int i = 0; i < 150; ++i) {
    ASSERT_TRUE(w.truth().lead_present) << "step " << i;
    double v = w.ego().speed;
    // Throttle while one more throttle step still leaves room to stop 1 m behind the leader.
    double v_next = m.next_speed(kThrottle, v, dt);
    if (!braking &&
        w.truth().lead_distance - v_next * dt - stopping_distance(m, v_next, dt) < 1.0)
      braking = true;
    StepResult r = w.step(braking ? kBrake : kThrottle);
    ASSERT_EQ(r.outcome, Outcome::Running)
        << "step " << i << ": " << outcome_name(r.outcome) << " with " << r.collided_with
        << ", lead_distance " << w.truth().lead_distance;
  }
  EXPECT_TRUE(braking);
  EXPECT_EQ(w.ego().speed, 0.0);
  ASSERT_TRUE(w.truth().lead_present);
  EXPECT_GT(w.truth().lead_distance, 0.0);
  EXPECT_LT(w.truth().lead_distance, 3.0) << "the ego should have stopped close behind";
  const Actor* a = find_actor(w, id);
  ASSERT_NE(a, nullptr);
  EXPECT_GT(gap_to(w, a->box), 0.0);
  EXPECT_LT(gap_to(w, a->box), 3.0);
  EXPECT_GT(w.ego().progress, 15.0);
}

TEST(WorldCollision, OncomingVehicleOnTheOppositeLaneIsNoCollision) {
  CD_NEEDS_SUMO();
  World w(test_settings());
  ASSERT_FALSE(reset_with_room(w, 45, /*grid_edge=*/true).route.empty());
  const LaneGeom* own = w.map().find(w.route_lanes().front());
  ASSERT_NE(own, nullptr);
  // The reverse of grid edge "B2B3" is "B3B2"; its car lane is the edge's highest lane index
  // (index 0 is the sidewalk).
  const std::string& e = own->edge;
  const std::string reverse = e.substr(2) + e.substr(0, 2);
  const LaneGeom* opposite = nullptr;
  for (const LaneGeom& g : w.map().lanes)
    if (g.edge == reverse && g.kind == LaneKind::Driving && !g.internal &&
        (!opposite || g.index > opposite->index))
      opposite = &g;
  ASSERT_NE(opposite, nullptr) << "no driving lane on " << reverse;
  ASSERT_NEAR(opposite->length, own->length, 1.0);
  // Opposite lane positions run the other way: start 45 m ahead of the ego, driving at it.
  const double pos = opposite->length - (w.ego().lane_pos + 45);
  ASSERT_GT(pos, 5.0);
  std::string id = add_vehicle(w, opposite->id, pos, 10.0);
  ASSERT_FALSE(id.empty());
  double closest = 1e9;
  bool passed = false;
  for (int i = 0; i < 50; ++i) {
    StepResult r = w.step(kThrottle);
    ASSERT_EQ(r.outcome, Outcome::Running)
        << "step " << i << ": " << outcome_name(r.outcome) << " with " << r.collided_with;
    if (const Actor* a = find_actor(w, id)) {
      Vec2 d = a->box.center - w.ego().pose.pos;
      closest = std::min(closest, d.norm());
      if (d.dot(fwd(w.ego().pose)) < -5) passed = true;
      // It is on the other lane, not on the ego's path.
      EXPECT_GT(std::abs(d.dot(lft(w.ego().pose))), 2.5) << "step " << i;
    }
  }
  EXPECT_TRUE(passed) << "the oncoming vehicle never got behind the ego";
  EXPECT_LT(closest, 5.0) << "the vehicles never came close: the test proves nothing";
}

// ---------------------------------------------------------------------------------------------
// Red lights

// Independent check of a red-light violation: before the step the ego was on a normal lane
// with a red light less than 10 m ahead, after it the ego is inside the junction.
struct RedLightOracle {
  int violations = 0;
  int passages = 0;
  int entered = kTlNone;
  std::string lane;
  int tl_state = kTlNone;
  double tl_distance = 0;

  void before(const World& w) {
    lane = w.ego().lane;
    tl_state = w.truth().tl_state;
    tl_distance = w.truth().tl_distance;
  }
  bool after(const World& w) {
    bool was_internal = !lane.empty() && lane[0] == ':';
    bool now_internal = !w.ego().lane.empty() && w.ego().lane[0] == ':';
    bool ran = !was_internal && now_internal && tl_state == kTlRed && tl_distance < 10.0;
    if (ran) ++violations;
    // Any light state: the junction entry the green-light rate counts (kTlNone: none).
    entered = !was_internal && now_internal && tl_distance < 10.0 ? tl_state : kTlNone;
    passages += entered != kTlNone;
    return ran;
  }
};

TEST(WorldRedLight, FullThrottleRunsRedLightsAndTheyAreCounted) {
  CD_NEEDS_SUMO();
  Settings s = test_settings();
  World w(s);
  int total_reported = 0, total_oracle = 0, total_passages = 0;
  for (uint64_t seed = 0; seed < 30; ++seed) {
    w.reset(w.sample_task(seed, 100, 200));
    RedLightOracle oracle;
    StepResult r;
    for (int i = 0; i < 600 && r.outcome == Outcome::Running; ++i) {
      const int before = w.counters().red_light_violations;
      oracle.before(w);
      r = w.step(kThrottle);
      ASSERT_NE(r.outcome, Outcome::Collision) << "seed " << seed << ": " << r.collided_with;
      bool ran = oracle.after(w);
      EXPECT_EQ(r.ran_red_light, ran)
          << "seed " << seed << " step " << i << ": entered " << w.ego().lane << " from "
          << oracle.lane << " with tl_state " << oracle.tl_state << " at "
          << oracle.tl_distance << " m";
      EXPECT_EQ(w.counters().red_light_violations, before + (r.ran_red_light ? 1 : 0))
          << "seed " << seed << " step " << i;
      EXPECT_EQ(r.entered_light, oracle.entered) << "seed " << seed << " step " << i;
    }
    total_passages += oracle.passages;
    EXPECT_EQ(w.counters().red_light_violations, oracle.violations) << "seed " << seed;
    total_reported += w.counters().red_light_violations;
    total_oracle += oracle.violations;
  }
  EXPECT_GT(total_oracle, 0) << "full throttle through 30 tasks never met a red light";
  EXPECT_GT(total_passages, total_oracle) << "full throttle never entered a light on green";
  EXPECT_EQ(total_reported, total_oracle);
}

TEST(WorldRedLight, ExpertNeverRunsARedLight) {
  CD_NEEDS_SUMO();
  Settings s = test_settings();
  World w(s);
  Autopilot expert(s.expert);
  int met_red = 0;
  for (uint64_t seed = 0; seed < 12; ++seed) {
    Task task = w.sample_task(seed, 100, 200);
    w.reset(task);
    RedLightOracle oracle;
    StepResult r;
    bool saw_red_close = false;
    int steps = 0;
    for (; steps < 5000 && r.outcome == Outcome::Running; ++steps) {
      if (w.truth().tl_state == kTlRed && w.truth().tl_distance < 15.0) saw_red_close = true;
      oracle.before(w);
      r = w.step(expert.act(w));
      oracle.after(w);
      EXPECT_FALSE(r.ran_red_light) << "seed " << seed << " step " << steps;
    }
    EXPECT_EQ(oracle.violations, 0) << "seed " << seed;
    EXPECT_EQ(w.counters().red_light_violations, 0) << "seed " << seed;
    EXPECT_EQ(r.outcome, Outcome::Success)
        << "seed " << seed << ": " << outcome_name(r.outcome) << " " << r.collided_with
        << " after " << steps << " steps";
    met_red += saw_red_close;
  }
  EXPECT_GT(met_red, 0) << "the expert never had to stop for a red light: the test proves nothing";
}

// Every light-controlled junction on the route is one junction entry (StepResult::entered_light,
// what the green-light rate and red-light violations count), in both lateral modes: the oracle
// is the route's lane sequence at reset (a normal lane followed by a signalised junction lane),
// not the ground truth. A free ego's SUMO stand-in often stands for a step at the very end of
// its approach lane, where the light is 0 m ahead: such entries were once missed.
TEST(WorldRedLight, EveryLightOnTheRouteIsOneJunctionEntryInBothModes) {
  CD_NEEDS_SUMO();
  for (const char* mode : {"route", "free"}) {
    Settings s = test_settings();
    s.ego.lateral = mode;
    World w(s);
    Autopilot expert(s.expert);
    int total = 0;
    for (uint64_t seed = 0; seed < 6; ++seed) {
      w.reset(w.sample_task(seed, 150, 300));
      int lights = 0;
      const std::vector<std::string> lanes = w.route_lanes();
      for (size_t i = 1; i < lanes.size(); ++i) {
        const ViaInfo* via = w.network().find_via(lanes[i]);
        lights += lanes[i - 1][0] != ':' && lanes[i][0] == ':' && via && !via->tls.empty();
      }
      int entries = 0;
      StepResult r;
      while (r.outcome == Outcome::Running) {
        r = w.step(expert.act(w));
        entries += r.entered_light != kTlNone;
      }
      ASSERT_EQ(r.outcome, Outcome::Success) << mode << " seed " << seed;
      EXPECT_EQ(entries, lights) << mode << " seed " << seed;
      total += lights;
    }
    EXPECT_GT(total, 6) << mode << ": too few lights on the routes for the test to say much";
  }
}

// ---------------------------------------------------------------------------------------------
// BEV of the live world

TEST(WorldBev, VehicleAheadLandsWhereTheConventionSays) {
  CD_NEEDS_SUMO();
  Settings s = test_settings();
  World w(s);
  ASSERT_FALSE(reset_with_room(w, 30).route.empty());
  std::string id = add_vehicle(w, w.route_lanes().front(), w.ego().lane_pos + 15, 0.0);
  ASSERT_FALSE(id.empty());
  const Actor* a = find_actor(w, id);
  ASSERT_NE(a, nullptr);
  const Pose2& ego = w.ego().pose;
  const double forward = (a->box.center - ego.pos).dot(fwd(ego));
  const double left = (a->box.center - ego.pos).dot(lft(ego));
  EXPECT_NEAR(gap_to(w, a->box), 10.0, 0.5) << "the vehicle should be 10 m ahead";
  EXPECT_NEAR(left, 0.0, 0.2) << "the vehicle should be straight ahead";

  const BevConfig& bc = w.renderer().config();
  const int H = bc.height, W = bc.width;
  std::vector<uint8_t> frame(w.renderer().frame_bytes());
  ASSERT_EQ(frame.size(), size_t(kBevChannelCount) * H * W);
  w.render(frame.data());
  auto px = [&](int ch, int r, int c) { return frame[(size_t(ch) * H + r) * W + c]; };
  auto pixel_of = [&](double fwd_m, double left_m) {
    double row = H * bc.ego_row_fraction - fwd_m / bc.metres_per_pixel;
    double col = W / 2.0 - left_m / bc.metres_per_pixel;
    return std::pair<int, int>{static_cast<int>(std::floor(row)), static_cast<int>(std::floor(col))};
  };
  auto [vr, vc] = pixel_of(forward, left);
  ASSERT_GE(vr, 0);
  ASSERT_LT(vr, H);
  EXPECT_EQ(px(kBevVehicles, vr, vc), 255) << "vehicle centre pixel (" << vr << ", " << vc << ")";
  auto [er, ec] = pixel_of(0, 0);
  EXPECT_EQ(px(kBevVehicles, er, ec), 0) << "the ego is not drawn in the vehicle channel";
  EXPECT_EQ(px(kBevDrivable, er, ec), 255) << "the ego stands on drivable area";
  EXPECT_EQ(px(kBevRoute, er, ec), 255) << "the ego stands on its route";
  // Just beyond the vehicle's far end and beside it, the vehicle channel is empty again.
  auto [br, bcol] = pixel_of(forward + a->box.length / 2 + 1.5, 0);
  if (br >= 0) {
    EXPECT_EQ(px(kBevVehicles, br, bcol), 0) << "beyond the vehicle";
  }
  auto [sr, sc] = pixel_of(forward, a->box.width / 2 + 1.5);
  EXPECT_EQ(px(kBevVehicles, sr, sc), 0) << "left of the vehicle";
  // Between the ego's front and the vehicle there is free road.
  auto [gr, gc] = pixel_of(s.ego.length / 2 + 5.0, 0);
  EXPECT_EQ(px(kBevVehicles, gr, gc), 0) << "the gap";
  EXPECT_EQ(px(kBevDrivable, gr, gc), 255) << "the gap is road";
}

// ---------------------------------------------------------------------------------------------
// Ground truth

TEST(WorldTruth, LeadDistanceAndPathFree) {
  CD_NEEDS_SUMO();
  Settings s = test_settings();
  World w(s);
  Task task = reset_with_room(w, 50);
  ASSERT_FALSE(task.route.empty());
  // Nothing on the road: no leader, the path is free.
  w.step(kBrake);
  EXPECT_FALSE(w.truth().lead_present);
  EXPECT_TRUE(w.truth().path_free);

  struct Case {
    double gap;
    bool path_free;
  };
  for (Case c : {Case{20.0, true}, Case{3.0, false}, Case{40.0, true}}) {
    SCOPED_TRACE("gap " + std::to_string(c.gap));
    w.reset(task);
    const std::string lane = w.route_lanes().front();
    const double ego_pos = w.ego().lane_pos;
    // The scripted vehicle's position is its front bumper: its rear lies one length behind.
    std::string id = w.add_scripted_vehicle(lane, ego_pos + c.gap + 5.0, 0.0);
    w.step(kBrake);
    const Actor* a = find_actor(w, id);
    ASSERT_NE(a, nullptr) << "scripted vehicle not inserted";
    const double gap = ego_pos + c.gap + 5.0 - a->box.length - w.ego().lane_pos;
    for (int i = 0; i < 3; ++i) w.step(kBrake);  // stays stopped
    EXPECT_EQ(w.ego().speed, 0.0);
    ASSERT_TRUE(w.truth().lead_present);
    EXPECT_NEAR(w.truth().lead_distance, gap, 1.0);
    EXPECT_NEAR(w.truth().lead_distance, gap_to(w, a->box), 1.0);
    EXPECT_NEAR(w.truth().lead_speed, 0.0, 0.01);
    EXPECT_EQ(w.truth().path_free, c.path_free)
        << "lead at " << w.truth().lead_distance << " m, path_free_distance "
        << w.truth().path_free_distance << ", tl " << w.truth().tl_state << " at "
        << w.truth().tl_distance;
  }
}

// ---------------------------------------------------------------------------------------------
// Errors

TEST(WorldErrors, MissingNetworkFileIsIoError) {
  CD_NEEDS_SUMO();
  Settings s = test_settings();
  s.world.town = "/nonexistent.net.xml";
  EXPECT_THROW({ World w(s); }, IoError);
}

TEST(WorldErrors, GarbageNetworkFileIsSimErrorNamingTheFile) {
  CD_NEEDS_SUMO();
  TempDir dir("cdtest-world");
  const std::string net = dir / "x.net.xml";
  test::write_text(net, "not xml\n");
  Settings s = test_settings();
  s.world.town = net;
  try {
    World w(s);
    FAIL() << "a garbage network was accepted";
  } catch (const SimError& e) {
    EXPECT_NE(std::string(e.what()).find("x.net.xml"), std::string::npos) << e.what();
  }
  // The failed start leaves the process able to run a World.
  s.world.town = "town-a";
  World ok(s);
  ok.reset(ok.sample_task(0, 100, 200));
  EXPECT_EQ(ok.step(kThrottle).outcome, Outcome::Running);
}

TEST(WorldErrors, UnknownTownNameIsConfigError) {
  CD_NEEDS_SUMO();
  Settings s = test_settings();
  s.world.town = "town-zzz";
  try {
    World w(s);
    FAIL() << "an unknown town was accepted";
  } catch (const ConfigError& e) {
    std::string msg = e.what();
    EXPECT_NE(msg.find("town-zzz"), std::string::npos) << msg;
    EXPECT_NE(msg.find("town-a"), std::string::npos) << "should list the known towns: " << msg;
  }
}

}  // namespace
}  // namespace cd
