// A free-steering ego (ego.lateral = "free", issue 13): the kinematic bicycle against an
// independent fine integration of its equations and hand-computed poses, the lane contact
// events on a hand-made road and on a scripted drive in the simulator, and the steering expert in closed loop on every built-in town and
// on a random network generated here.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <regex>
#include <set>
#include <string>

#include "../support/test_support.hpp"
#include "app/settings.hpp"
#include "core/error.hpp"
#include "expert/autopilot.hpp"
#include "world/ego_model.hpp"
#include "world/lane_contact.hpp"
#include "world/world.hpp"

namespace cd {
namespace {

EgoSettings bicycle() {
  EgoSettings e;
  e.wheelbase = 2.7;
  e.max_steer = 0.6;
  e.steer_rate = 1.0;
  return e;
}

TEST(Bicycle, StraightStepsMoveAlongTheHeading) {
  const EgoModel m(bicycle());
  const Pose2 p = m.next_pose({{10, 20}, M_PI / 6}, 8.0, 12.0, 0.0, 0.1);  // mean speed 10
  EXPECT_NEAR(p.pos.x, 10 + std::cos(M_PI / 6), 1e-12);
  EXPECT_NEAR(p.pos.y, 20 + std::sin(M_PI / 6), 1e-12);
  EXPECT_DOUBLE_EQ(p.heading, M_PI / 6);
}

TEST(Bicycle, ArcsAgreeWithAFineIntegrationAndTheHandComputedCircle) {
  const EgoModel m(bicycle());
  const double angle = 0.3, v = 5.0, dt = 0.1;
  // Hand computation: slip angle beta = atan(tan(0.3) / 2) = atan(0.154668) = 0.153452, the
  // centre circles with radius R = (L / 2) / sin(beta) = 1.35 / 0.152851 = 8.8321 m at yaw rate
  // v / R.
  const double beta = std::atan(std::tan(angle) / 2), radius = 1.35 / std::sin(beta);
  EXPECT_NEAR(beta, 0.153452, 1e-6);
  EXPECT_NEAR(radius, 8.8321, 1e-3);
  Pose2 p{{0, 0}, 0}, q = p;
  for (int k = 0; k < 40; ++k) {
    p = m.next_pose(p, v, v, angle, dt);
    // The ODE x' = v cos(h + beta), y' = v sin(h + beta), h' = v sin(beta) / (L / 2), in steps
    // of 1e-5 s (midpoint rule).
    for (int i = 0; i < 10000; ++i) {
      const double h = 1e-5, mid = q.heading + 0.5 * h * v * std::sin(beta) / 1.35;
      q.pos = q.pos + Vec2{std::cos(mid + beta), std::sin(mid + beta)} * (v * h);
      q.heading += h * v * std::sin(beta) / 1.35;
    }
    EXPECT_NEAR(p.pos.x, q.pos.x, 1e-6);
    EXPECT_NEAR(p.pos.y, q.pos.y, 1e-6);
    EXPECT_NEAR(p.heading, q.heading, 1e-9);
  }
  // After 4 s the heading turned v t / R, and the centre stays on its circle around
  // (-R sin(beta), R cos(beta)).
  EXPECT_NEAR(p.heading, v * 4.0 / radius, 1e-9);
  const Vec2 c{-radius * std::sin(beta), radius * std::cos(beta)};
  EXPECT_NEAR((p.pos - c).norm(), radius, 1e-9);
}

TEST(Bicycle, SteeringAngleIsRateLimitedAndBounded) {
  const EgoModel m(bicycle());
  EXPECT_NEAR(m.next_steer_angle(0.0, 1.0, 0.1), 0.1, 1e-12);    // 1 rad/s for 0.1 s
  EXPECT_NEAR(m.next_steer_angle(0.55, 1.0, 0.1), 0.6, 1e-12);   // up to max_steer
  EXPECT_NEAR(m.next_steer_angle(0.0, -0.05, 0.1), -0.03, 1e-12);  // reaches a near target
  EXPECT_NEAR(m.next_steer_angle(0.0, 5.0, 10.0), 0.6, 1e-12);   // steer clamped to [-1, 1]
}

// The lateral augmentation's label: pure pursuit from the shifted or rotated pose towards the
// same path point. Target 10 m ahead on the lane centre (x axis), L = 2.7, max_steer = 0.6.
TEST(AugmentationLabel, CorrectiveSteerHasTheHandComputedGeometry) {
  const EgoSettings e = bicycle();
  const Vec2 target{10, 0};
  EXPECT_NEAR(pursuit_steer({{0, 0}, 0}, target, e), 0.0, 1e-12);
  // Shifted 1 m left: the target at (10 + 1.35, -1) from the rear axle,
  // angle = atan(2 * 2.7 * -1 / (11.35^2 + 1)) = atan(-0.041596) = -0.041572 rad = -0.06929 steer.
  EXPECT_NEAR(pursuit_steer({{0, 1}, 0}, target, e), -0.069285, 1e-5);
  EXPECT_NEAR(pursuit_steer({{0, -1}, 0}, target, e), 0.069285, 1e-5);  // mirror image
  // Rotated 0.1 rad left: the target at (10 cos 0.1 + 1.35, -10 sin 0.1) = (11.300, -0.998),
  // angle = atan(-5.3916 / 128.686) = -0.041873 rad = -0.06978 steer.
  EXPECT_NEAR(pursuit_steer({{0, 0}, 0.1}, target, e), -0.069779, 1e-5);
  // Far off to the side the correction saturates at full lock.
  EXPECT_DOUBLE_EQ(pursuit_steer({{8, 6}, 0.5}, target, e), -1.0);
}

// The tracker's target on a planned path (dim and rip steer along their plan).
TEST(PathTarget, PointAlongAPolylineFromTheProjection) {
  const Polyline l = {{0, 0}, {10, 0}, {10, 10}};
  Vec2 p = point_along_polyline(l, {3, 1}, 4);  // projects to (3, 0): 4 m on is (7, 0)
  EXPECT_NEAR(p.x, 7, 1e-12);
  EXPECT_NEAR(p.y, 0, 1e-12);
  p = point_along_polyline(l, {8, -2}, 5);  // (8, 0) + 2 m to the corner + 3 m up
  EXPECT_NEAR(p.x, 10, 1e-12);
  EXPECT_NEAR(p.y, 3, 1e-12);
  p = point_along_polyline(l, {10, 9}, 4);  // beyond the end: along the last segment
  EXPECT_NEAR(p.x, 10, 1e-12);
  EXPECT_NEAR(p.y, 13, 1e-12);
}

// A two-way road along x (an eastbound lane below y = 0, a westbound one above), and a
// junction lane continuing the eastbound one beyond x = 100.
RoadMap two_way_road() {
  RoadMap map;
  auto lane = [&](const std::string& id, const std::string& edge, Polyline shape, bool internal) {
    LaneGeom g;
    g.id = id;
    g.edge = edge;
    g.internal = internal;
    g.width = 3.2;
    g.shape = shape;
    g.length = polyline_length(shape);
    map.add(g);
  };
  lane("east_0", "east", {{0, -1.6}, {100, -1.6}}, false);
  lane("west_0", "west", {{100, 1.6}, {0, 1.6}}, false);
  lane(":j_0_0", ":j_0", {{100, -1.6}, {110, -1.6}}, true);
  return map;
}

TEST(LaneContact, OnLaneOffsetWrongWayOffRoadAndJunction) {
  const RoadMap map = two_way_road();
  const LaneGrid grid(map);
  auto contact = [&](Vec2 c, double heading) {
    return road_contact(map, grid, Box{c, heading, 4.5, 1.8});
  };
  RoadContact rc = contact({50, -1.6}, 0.0);  // centred on its lane
  EXPECT_EQ(map.lanes[rc.lane].id, "east_0");
  EXPECT_FALSE(rc.offroad || rc.wrong_way || rc.lane_invasion);
  EXPECT_NEAR(rc.lateral_error, 0.0, 1e-12);
  rc = contact({50, -1.3}, 0.2);  // 0.3 m left, turned 0.2 rad: the left front corner is at
  // y = -1.3 + 2.25 sin(0.2) + 0.9 cos(0.2) = 0.028 > 0, over the centre line
  EXPECT_NEAR(rc.lateral_error, 0.3, 1e-12);
  EXPECT_NEAR(rc.heading_error, 0.2, 1e-12);
  EXPECT_TRUE(rc.lane_invasion);
  EXPECT_FALSE(rc.wrong_way);
  rc = contact({50, -1.6}, 0.1);  // turned less: its corners stay within the lane (|y| < 3.2)
  EXPECT_FALSE(rc.lane_invasion);
  rc = contact({50, 1.6}, 0.0);  // on the westbound lane, heading east
  EXPECT_TRUE(rc.wrong_way);
  EXPECT_FALSE(rc.offroad);
  rc = contact({50, 1.6}, M_PI);  // the same place heading west: its own lane
  EXPECT_FALSE(rc.wrong_way);
  EXPECT_EQ(map.lanes[rc.lane].id, "west_0");
  rc = contact({50, -2.8}, 0.0);  // its right side beyond the road's edge (y < -3.2)
  EXPECT_FALSE(rc.offroad);
  EXPECT_TRUE(rc.lane_invasion);
  EXPECT_NEAR(rc.lateral_error, -1.2, 1e-12);
  rc = contact({50, -3.8}, 0.0);  // the centre off the road, the left corners still on it
  EXPECT_FALSE(rc.offroad);
  EXPECT_EQ(rc.lane, -1);
  rc = contact({50, -6.0}, 0.0);  // every point beyond the lane's surface
  EXPECT_TRUE(rc.offroad);
  EXPECT_EQ(rc.lane, -1);
  rc = contact({99, -1.6}, 0.0);  // front half in the junction: no invasion
  EXPECT_FALSE(rc.lane_invasion);
  EXPECT_FALSE(rc.offroad);
  rc = contact({300, 0}, 0.0);  // outside the map
  EXPECT_TRUE(rc.offroad);
}

// The expert with the wheel drives `task` to its goal, on the road.
void expert_drives_task(World& w, const Settings& s, const Task& task, const std::string& what) {
  const Autopilot expert(s.expert);
  w.reset(task);
  StepResult r;
  double worst = 0;
  while (r.outcome == Outcome::Running) {
    r = w.step(expert.act(w));
    worst = std::max(worst, std::abs(w.road_contact().lateral_error));
  }
  EXPECT_EQ(outcome_name(r.outcome), std::string("success")) << what;
  EXPECT_EQ(w.counters().wrong_way, 0) << what;
  EXPECT_LT(worst, 1.6) << what << ": the centre left its lane";
  EXPECT_LT(w.counters().lateral_error_sum / std::max<long>(1, w.counters().lateral_samples), 0.3)
      << what;
}

Settings free_settings(const test::TempDir& dir, const std::string& town) {
  Settings s = load_settings(test::write_test_config(dir, "empty"));
  s.world.town = town;
  s.ego.lateral = "free";
  return s;
}

// The expert with the wheel drives a sampled task of `town` to its goal, on the road.
void expert_drives(const std::string& town, uint64_t seed) {
  test::TempDir dir("cdtest-steer");
  const Settings s = free_settings(dir, town);
  World w(s);
  expert_drives_task(w, s, w.sample_task(seed, 150, 400), town + " seed " + std::to_string(seed));
}

TEST(SteeringExpert, DrivesEveryBuiltInTown) {
  CD_NEEDS_SUMO();
  for (const char* town : {"town-a", "town-b", "town-c"})
    for (uint64_t seed : {1, 2}) expert_drives(town, seed);
}

// A random one-lane network that netgenerate draws with seed 17 (with U-turn links, or built
// without them as the built-in towns are), written to `file`.
void random_network(const std::string& file, bool turnarounds) {
  std::vector<std::string> argv = {
      "/usr/bin/netgenerate", "--rand", "--rand.iterations", "40", "--rand.min-distance", "70",
      "--rand.max-distance", "140", "--rand.min-angle", "50", "--seed", "17",
      "--default.lanenumber", "1", "--tls.guess", "-o", file};
  if (!turnarounds) argv.insert(argv.end(), {"--no-turnarounds", "true"});
  const test::CommandResult r = test::run_command(argv);
  ASSERT_TRUE(r.exited && r.exit_code == 0) << r.describe();
}

TEST(SteeringExpert, DrivesARandomNetworkItHasNeverSeen) {
  CD_NEEDS_SUMO();
  test::TempDir dir("cdtest-steer-net");
  const std::string net = dir / "random.net.xml";
  ASSERT_NO_FATAL_FAILURE(random_network(net, false));
  for (uint64_t seed : {3, 4, 5}) expert_drives(net, seed);
}

// Networks imported from OSM (and netgenerate's, unless told --no-turnarounds) have U-turn
// links. A free ego's turning circle is too wide for them: on sumo-tools' DRT network the expert
// left the road at the end of 6 of 12 drawn routes, each a U-turn onto the reverse edge. No task
// is drawn through one, in either mode. (On this network, half the routes drawn before the fix
// turned around.) The oracle is the network file's own connections.
TEST(TaskSampling, NoRouteTurnsAround) {
  CD_NEEDS_SUMO();
  test::TempDir dir("cdtest-uturn");
  const std::string net = dir / "uturns.net.xml";
  ASSERT_NO_FATAL_FAILURE(random_network(net, true));
  std::set<std::pair<std::string, std::string>> uturn, other;
  const std::string text = test::read_text(net);
  const std::regex conn(R"re(<connection from="([^":][^"]*)" to="([^"]+)"[^>]*dir="(.)")re");
  for (auto it = std::sregex_iterator(text.begin(), text.end(), conn); it != std::sregex_iterator();
       ++it) {
    const std::string dir_code = (*it)[3];
    (dir_code == "t" || dir_code == "T" ? uturn : other).insert({(*it)[1], (*it)[2]});
  }
  ASSERT_GT(uturn.size(), 50u) << "the network was meant to have U-turn links";
  for (const char* mode : {"free", "route"}) {
    Settings s = free_settings(dir, net);
    s.ego.lateral = mode;
    World w(s);
    for (uint64_t seed = 1; seed <= 20; ++seed) {
      const Task t = w.sample_task(seed, 100, 400);
      ASSERT_GE(t.route.size(), 2u);
      for (size_t k = 0; k + 1 < t.route.size(); ++k) {
        const std::pair<std::string, std::string> step{t.route[k], t.route[k + 1]};
        EXPECT_FALSE(uturn.count(step) && !other.count(step))
            << mode << " seed " << seed << ": " << step.first << " -> " << step.second;
      }
    }
  }
}

// A scripted drive in the simulator (town-a: one lane per direction, 3.5 m wide, straight 110 m
// blocks): the ego steers towards a lateral offset from its start lane's centre line, first the
// opposing lane's centre (+3.5 m), then beyond the road (+12 m). The lane-invasion onset comes
// first (a corner across the centre line), then the wrong-way onset (the centre on the opposing
// lane), each counted once, and the episode ends as `offroad` once no point of the footprint is
// on a driving lane. Before the first swerve, driving on its own lane raises nothing.
TEST(WorldEvents, ScriptedSwerveInvadesGoesWrongWayThenLeavesTheRoad) {
  CD_NEEDS_SUMO();
  test::TempDir dir("cdtest-steer-events");
  const Settings s = free_settings(dir, "town-a");
  World w(s);
  Task task;
  for (uint64_t seed = 1; seed < 200 && task.route.empty(); ++seed) {
    const Task t = w.sample_task(seed, 150, 400);
    if (w.network().rightmost_lane(t.route.front()).length - t.start_pos > 60) task = t;
  }
  ASSERT_FALSE(task.route.empty()) << "no town-a task with 60 m of its first edge ahead";
  w.reset(task);
  const LaneGeom lane = *w.map().find(w.ego().lane);  // the start lane, a straight line
  // Steer towards `offset` m left of the start lane's centre line: a PD law on the offset
  // (the desired heading error is proportional to the offset still to go).
  auto towards = [&](double offset) {
    const LaneProjection p = project_on_lane(lane, w.ego().pose.pos);
    const double want = std::clamp(0.15 * (offset - p.lateral), -0.5, 0.5);
    const double heading = wrap_angle(w.ego().pose.heading - p.direction);
    const double speed = w.ego().speed;
    return Control{speed < 6.0 ? 0.5 : 0.0, 0.0, std::clamp(2.0 * (want - heading), -1.0, 1.0)};
  };
  StepResult r;
  for (int i = 0; i < 30; ++i) {  // gather speed on the lane
    r = w.step(towards(0.0));
    ASSERT_EQ(r.outcome, Outcome::Running);
    EXPECT_FALSE(r.lane_invasion || r.wrong_way) << "step " << i;
  }
  EXPECT_EQ(w.counters().lane_invasions, 0);
  EXPECT_EQ(w.counters().wrong_way, 0);
  int invasion_step = -1, wrong_way_step = -1;
  for (int i = 0; i < 100 && wrong_way_step < 0; ++i) {
    r = w.step(towards(3.5));
    ASSERT_EQ(r.outcome, Outcome::Running) << "step " << i;
    if (r.lane_invasion && invasion_step < 0) invasion_step = i;
    if (r.wrong_way) wrong_way_step = i;
  }
  ASSERT_GE(invasion_step, 0) << "no lane invasion while crossing the centre line";
  ASSERT_GE(wrong_way_step, 0) << "the centre on the opposing lane was not wrong way";
  EXPECT_LT(invasion_step, wrong_way_step);
  EXPECT_GT(project_on_lane(lane, w.ego().pose.pos).lateral, 1.75) << "wrong way on its own lane";
  EXPECT_EQ(w.counters().wrong_way, 1);
  EXPECT_GE(w.counters().lane_invasions, 1);
  EXPECT_TRUE(w.road_contact().wrong_way);
  EXPECT_FALSE(w.road_contact().offroad);
  double last_lateral = 0;
  for (int i = 0; i < 150 && r.outcome == Outcome::Running; ++i) {
    last_lateral = project_on_lane(lane, w.ego().pose.pos).lateral;
    r = w.step(towards(12.0));
  }
  EXPECT_EQ(outcome_name(r.outcome), std::string("offroad"));
  // Off the road: the whole footprint beyond the opposing lane's far edge (+5.25 m), give or
  // take half the footprint's diagonal sweep in one step.
  EXPECT_GT(last_lateral, 5.25);
  EXPECT_EQ(w.counters().wrong_way, 1) << "one onset while on the opposing lane";
}

// town-c has two lanes per direction and starts a free ego on the rightmost: routes that turn
// left from it need a lane change, which the expert makes (SUMO's stand-in follows it to the
// new lane); SUMO cannot drive such a route for a route-mode ego, which refuses the task.
TEST(SteeringExpert, ChangesLanesWhereTheRouteNeedsIt) {
  CD_NEEDS_SUMO();
  test::TempDir dir("cdtest-steer-lc");
  Task task;
  {
    const Settings s = free_settings(dir, "town-c");
    World w(s);
    for (uint64_t seed = 1; seed < 200 && task.route.empty(); ++seed) {
      const Task t = w.sample_task(seed, 150, 400);
      if (!w.network().lane_changes(t.route, t.start_lane).empty()) task = t;
    }
    ASSERT_FALSE(task.route.empty()) << "no town-c task with a lane change in 200 seeds";
    expert_drives_task(w, s, task, "town-c lane change");
    EXPECT_GE(w.counters().lane_changes,
              static_cast<int>(w.network().lane_changes(task.route, task.start_lane).size()));
  }
  Settings route = free_settings(dir, "town-c");
  route.ego.lateral = "route";
  World w(route);
  try {
    w.reset(task);
    FAIL() << "a route-mode ego accepted a task that needs a lane change";
  } catch (const SimError& e) {
    EXPECT_NE(std::string(e.what()).find("lane change"), std::string::npos) << e.what();
  }
}

// A car on the lane the ego must join, beside it at the start: the expert does not cut in; it
// changes only once it is clear of the car (its front more than a car length and a gap ahead),
// and drives the route to its end.
TEST(SteeringExpert, ChangesLanesOnlyWhereTheTargetLaneIsClear) {
  CD_NEEDS_SUMO();
  test::TempDir dir("cdtest-steer-lc-gap");
  const Settings s = free_settings(dir, "town-c");
  World w(s);
  Task task;
  LaneChange first;
  for (uint64_t seed = 1; seed < 400 && task.route.empty(); ++seed) {
    const Task t = w.sample_task(seed, 150, 400);
    const std::vector<LaneChange> ch = w.network().lane_changes(t.route, t.start_lane);
    if (!ch.empty() && w.network().map.find(ch[0].from)->edge == t.route.front() &&
        w.network().rightmost_lane(t.route.front()).length - t.start_pos > 60) {
      task = t;
      first = ch[0];
    }
  }
  ASSERT_FALSE(task.route.empty()) << "no town-c task changing lanes on its first edge";
  w.reset(task);
  const LaneGeom& to = *w.network().map.find(first.to);
  const std::string car = w.add_scripted_vehicle(first.to, w.ego().lane_pos + 6.0, 0.0);
  const Autopilot expert(s.expert);
  StepResult r;
  // The ego's front ahead of the car's centre, along the new lane, when its footprint first
  // crosses onto that lane (the first lane invasion).
  double gap = -1e9;
  while (r.outcome == Outcome::Running) {
    r = w.step(expert.act(w));
    if (r.lane_invasion && gap < -1e8)
      for (const Actor& a : w.actors())
        if (a.id == car) gap = w.ego().lane_pos - project_on_lane(to, a.box.center).along;
  }
  EXPECT_EQ(outcome_name(r.outcome), std::string("success"));
  EXPECT_GE(w.counters().lane_changes, 1);
  ASSERT_GT(gap, -1e8) << "the ego never crossed onto the new lane";
  // The rule for a stopped car: the ego's length, 3 m and half the car's length.
  EXPECT_GE(gap, s.ego.length + 3.0 + 2.5);
}

}  // namespace
}  // namespace cd
