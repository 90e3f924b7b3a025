// The world's pure parts on a network built by hand, without SUMO: lane planning on the road
// network, the path's geometry, the ground truth (what "path free" means) and the recorded
// cause schema. Expected values are worked out by hand from the coordinates below.
#include <gtest/gtest.h>

#include <algorithm>
#include <string>
#include <vector>

#include "world/ground_truth.hpp"
#include "world/road_network.hpp"
#include "world/route_path.hpp"

namespace cd {
namespace {

LaneGeom lane(const std::string& id, const std::string& edge, Vec2 a, Vec2 b, bool internal) {
  LaneGeom g;
  g.id = id;
  g.edge = edge;
  g.internal = internal;
  g.width = 3.2;
  g.length = (b - a).norm();
  g.shape = {a, b};
  return g;
}

// Edge A (0,0)->(100,0), a junction lane :J_0_0 (100,0)->(110,0) behind a light, edge B
// (110,0)->(210,0); a second lane A_1 of edge A has no link to B.
RoadNetwork straight_network() {
  RoadNetwork net;
  net.map.add(lane("A_0", "A", {0, 0}, {100, 0}, false));
  LaneGeom a1 = lane("A_1", "A", {0, 3.2}, {100, 3.2}, false);
  a1.index = 1;
  net.map.add(a1);
  net.map.add(lane(":J_0_0", ":J", {100, 0}, {110, 0}, true));
  net.map.add(lane("B_0", "B", {110, 0}, {210, 0}, false));
  net.links["A_0"] = {{"B_0", ":J_0_0", 's'}};
  net.links[":J_0_0"] = {{"B_0", "", 's'}};
  net.via_info[":J_0_0"] = ViaInfo{"A_0", 's', 'O', "light", 0};
  net.via_head[":J_0_0"] = ":J_0_0";
  net.edge_lanes["A"] = {"A_0", "A_1"};
  net.edge_lanes["B"] = {"B_0"};
  net.edge_lane["A"] = 0;
  net.edge_lane["B"] = 3;
  return net;
}

const std::vector<std::string> kRoute = {"A", "B"};

TEST(RoadNetwork, PlansLanesWithoutASimulator) {
  const RoadNetwork net = straight_network();
  const LanePlan plan = net.lane_plan(kRoute);
  ASSERT_EQ(plan.size(), 2u);
  EXPECT_EQ(plan[1], (std::unordered_set<std::string>{"B_0"}));
  EXPECT_EQ(plan[0], (std::unordered_set<std::string>{"A_0"})) << "A_1 cannot reach B";
  EXPECT_EQ(net.next_lane("A_0", "B", &plan[1]), ":J_0_0");
  EXPECT_EQ(net.next_lane("A_1", "B", &plan[1]), "");
  size_t k = 0;
  EXPECT_EQ(net.lane_after(kRoute, plan, "A_0", k), ":J_0_0");
  EXPECT_EQ(net.lane_after(kRoute, plan, ":J_0_0", k), "B_0");
  EXPECT_EQ(net.lane_after(kRoute, plan, "B_0", k), "") << "the route ends on B";
  EXPECT_EQ(net.first_via(kRoute, 0), ":J_0_0");
  EXPECT_EQ(net.rightmost_lane("B").id, "B_0");
  ASSERT_NE(net.find_via(":J_0_0"), nullptr);
  EXPECT_EQ(net.find_via(":J_0_0")->tls, "light");
  EXPECT_EQ(net.find_via("A_0"), nullptr);
  EXPECT_TRUE(net.foes_of(":J_0_0").empty());
}

TEST(RoutePath, GeometryAlongTheRoute) {
  const RoadNetwork net = straight_network();
  const LanePlan plan = net.lane_plan(kRoute);
  // The ego's front at 40 m along A_0: A_0 from 40 (s 0), the junction (s 60), B_0 (s 70).
  const RoutePath path = trace_route_path(net, kRoute, plan, "A_0", 40, 80);
  ASSERT_EQ(path.lanes.size(), 3u);
  EXPECT_DOUBLE_EQ(path.lanes[1].s_begin, 60);
  EXPECT_DOUBLE_EQ(path.lanes[2].s_begin, 70);
  EXPECT_EQ(path.lanes[2].lane->id, "B_0");
  EXPECT_DOUBLE_EQ(path.max.x, 210);

  const Vec2 p10 = path.point(10, {0, 0}), p65 = path.point(65, {0, 0});
  EXPECT_DOUBLE_EQ(p10.x, 50);
  EXPECT_DOUBLE_EQ(p65.x, 105);
  EXPECT_DOUBLE_EQ(path.point(500, {0, 0}).x, 210) << "beyond the path: its last point";

  double s = -1;
  ASSERT_TRUE(path.locate({80, 1.0}, 1.5, &s));
  EXPECT_DOUBLE_EQ(s, 40);
  EXPECT_FALSE(path.locate({80, 2.0}, 1.5, &s)) << "too far beside the lane";
  EXPECT_FALSE(path.locate({20, 0}, 1.5, &s)) << "behind the ego's front";

  const auto line = path.line_across(60);  // the junction's entry
  ASSERT_TRUE(line.has_value());
  EXPECT_DOUBLE_EQ(line->first.x, 100);
  EXPECT_DOUBLE_EQ(line->first.y, 1.6);
  EXPECT_DOUBLE_EQ(line->second.y, -1.6);
  EXPECT_FALSE(path.line_across(300).has_value());
}

struct Junction {
  char light = 'G';
  bool blocked = false;
  std::vector<std::string> asked;
};

TruthStep truth_of(const RoadNetwork& net, const RoutePath& path, const std::vector<Actor>& actors,
                   double speed, const WorldSettings& ws, Junction& j,
                   Pose2 ego = Pose2{{38, 0}, 0}) {
  return compute_ground_truth(
      {net, path, actors, ego, speed, 1.8, ws,
       [&](const ViaInfo&) { return j.light; },
       [&](const std::string& lane, bool) {
         j.asked.push_back(lane);
         return j.blocked;
       }});
}

Actor car_at(double x, double speed) {
  return Actor{"car", Box{{x, 0}, 0, 4.0, 1.8}, speed, false};
}

// Lane changes. On straight_network, A_1 cannot reach B: a drive from A_1 changes to A_0.
TEST(RoadNetwork, PlansALaneChangeWhereTheRouteNeedsOne) {
  const RoadNetwork net = straight_network();
  const LanePlan plan = net.lane_plan(kRoute);
  EXPECT_EQ(net.change_lane(plan, "A_1", 0), "A_0");
  EXPECT_EQ(net.change_lane(plan, "A_0", 0), "") << "A_0 is planned";
  EXPECT_EQ(net.change_lane(plan, ":J_0_0", 0), "") << "never inside a junction";
  size_t k = 0;
  EXPECT_EQ(net.lane_after(kRoute, plan, "A_1", k), "A_0");
  ASSERT_EQ(net.lane_changes(kRoute, 1).size(), 1u);
  EXPECT_EQ(net.lane_changes(kRoute, 1)[0].from, "A_1");
  EXPECT_EQ(net.lane_changes(kRoute, 1)[0].to, "A_0");
  EXPECT_TRUE(net.lane_changes(kRoute, 0).empty());

  // A -> B -> C where A reaches only B's left lane and only B's right lane reaches C: no lane
  // of A drives the route without a change, so A's plan falls back to the lanes that reach B,
  // and the change happens on B.
  RoadNetwork n2;
  n2.map.add(lane("A_0", "A", {0, 0}, {100, 0}, false));
  for (int i : {0, 1}) {
    LaneGeom b = lane("B_" + std::to_string(i), "B", {100, 3.2 * i}, {200, 3.2 * i}, false);
    b.index = i;
    n2.map.add(b);
  }
  n2.map.add(lane("C_0", "C", {200, 0}, {300, 0}, false));
  n2.links["A_0"] = {{"B_1", "", 's'}};
  n2.links["B_0"] = {{"C_0", "", 's'}};
  n2.edge_lanes = {{"A", {"A_0"}}, {"B", {"B_0", "B_1"}}, {"C", {"C_0"}}};
  const std::vector<std::string> route = {"A", "B", "C"};
  const LanePlan p2 = n2.lane_plan(route);
  EXPECT_EQ(p2[1], (std::unordered_set<std::string>{"B_0"}));
  EXPECT_EQ(p2[0], (std::unordered_set<std::string>{"A_0"})) << "the fallback: A_0 reaches B";
  const std::vector<LaneChange> changes = n2.lane_changes(route, 0);
  ASSERT_EQ(changes.size(), 1u);
  EXPECT_EQ(changes[0].from, "B_1");
  EXPECT_EQ(changes[0].to, "B_0");
}

TEST(RoutePath, ALaneChangeSteersTheDiagonalAndHoldsForTraffic) {
  const RoadNetwork net = straight_network();
  const LanePlan plan = net.lane_plan(kRoute);
  LaneChangeOptions changes;
  changes.length = 20;
  // The front at 40 m on A_1: the change begins at once, ending on A_0 at 60 m.
  RoutePath path = trace_route_path(net, kRoute, plan, "A_1", 40, 200, changes);
  ASSERT_EQ(path.lanes.size(), 4u);
  EXPECT_EQ(path.lanes[0].lane->id, "A_1");
  EXPECT_DOUBLE_EQ(path.lanes[0].steer_to, 40);
  EXPECT_DOUBLE_EQ(path.lanes[0].to_pos, 60);
  EXPECT_EQ(path.lanes[1].lane->id, "A_0");
  EXPECT_DOUBLE_EQ(path.lanes[1].from_pos, 40);
  EXPECT_DOUBLE_EQ(path.lanes[1].steer_from, 60);
  EXPECT_DOUBLE_EQ(path.lanes[1].s_begin, 0);
  EXPECT_DOUBLE_EQ(path.lanes[2].s_begin, 60) << "the junction: 60 m on, as without a change";
  EXPECT_GE(path.hold, 1e299) << "nothing holds the change back";
  // The line to steer along: within the change, the point where it ends; then along A_0.
  EXPECT_NEAR(path.point(0, {}).x, 60, 1e-9);
  EXPECT_NEAR(path.point(0, {}).y, 0, 1e-9);
  EXPECT_NEAR(path.point(10, {}).x, 60, 1e-9);
  EXPECT_NEAR(path.point(25, {}).x, 65, 1e-9);
  // Both lanes hold what is on the path over the change's stretch.
  double s = -1;
  ASSERT_TRUE(path.locate({50, 3.2}, 1.0, &s));
  EXPECT_NEAR(s, 10, 1e-9);
  ASSERT_TRUE(path.locate({50, 0}, 1.0, &s));
  EXPECT_NEAR(s, 10, 1e-9);
  EXPECT_FALSE(path.locate({70, 3.2}, 1.0, &s)) << "A_1 beyond the change is off the path";

  // Traffic on A_0: the change begins as late as A_1 allows (100 - 20 - 1 = 79 m).
  changes.clear = [](const LaneGeom& to, double pos) {
    EXPECT_EQ(to.id, "A_0");
    EXPECT_NEAR(pos, 40, 1e-9);
    return false;
  };
  path = trace_route_path(net, kRoute, plan, "A_1", 40, 200, changes);
  EXPECT_NEAR(path.hold, 39, 1e-9);
  EXPECT_NEAR(path.point(10, {}).x, 50, 1e-9);
  EXPECT_NEAR(path.point(10, {}).y, 3.2, 1e-9);
  EXPECT_NEAR(path.point(50, {}).x, 99, 1e-9) << "inside the change: where it ends";
  EXPECT_NEAR(path.point(50, {}).y, 0, 1e-9);
  EXPECT_DOUBLE_EQ(path.lanes[2].s_begin, 60);
}

TEST(GroundTruth, LeaderLightAndPathFreeByHand) {
  const RoadNetwork net = straight_network();
  const LanePlan plan = net.lane_plan(kRoute);
  const RoutePath path = trace_route_path(net, kRoute, plan, "A_0", 40, 80);
  WorldSettings ws;  // path_free_decel 3, path_free_margin 6, command_horizon 30
  Junction j;
  // A car whose rear bumper is at x = 88: 48 m ahead of the ego's front (x = 40).
  TruthStep t = truth_of(net, path, {car_at(90, 2.0)}, 10.0, ws, j);
  EXPECT_TRUE(t.truth.lead_present);
  EXPECT_DOUBLE_EQ(t.truth.lead_distance, 48);
  EXPECT_DOUBLE_EQ(t.truth.lead_speed, 2.0);
  EXPECT_EQ(t.truth.tl_state, kTlGreen);
  EXPECT_DOUBLE_EQ(t.truth.tl_distance, 60);
  EXPECT_DOUBLE_EQ(t.truth.junction_distance, 60);
  EXPECT_DOUBLE_EQ(t.truth.junction_exit_distance, 70);
  EXPECT_EQ(t.command, kFollow) << "the junction is beyond command_horizon";
  // Stopping distance at 10 m/s and 3 m/s^2 is 16.7 m, + 6 m: the leader at 48 m is clear.
  EXPECT_NEAR(t.truth.path_free_distance, 100.0 / 6.0 + 6.0, 1e-12);
  EXPECT_TRUE(t.truth.path_free);
  EXPECT_FALSE(t.truth.must_yield);
  EXPECT_EQ(j.asked, std::vector<std::string>{":J_0_0"}) << "the junction's lanes are checked";

  // Path free is the benchmark's ([world]) definition: at 1 m/s^2 the distance is 56 m.
  ws.path_free_decel = 1.0;
  t = truth_of(net, path, {car_at(90, 2.0)}, 10.0, ws, j);
  EXPECT_DOUBLE_EQ(t.truth.path_free_distance, 56);
  EXPECT_FALSE(t.truth.path_free);

  // A red light 60 m ahead blocks once the stopping distance reaches it; the light state is
  // what the next step needs to detect a red-light violation.
  j.light = 'r';
  t = truth_of(net, path, {}, 10.0, ws, j);
  EXPECT_EQ(t.truth.tl_state, kTlRed);
  EXPECT_EQ(t.next_light_state, 'r');
  EXPECT_DOUBLE_EQ(t.next_light_distance, 60);
  EXPECT_TRUE(t.truth.path_free) << "56 m < 60 m";
  t = truth_of(net, path, {}, 11.0, ws, j);
  EXPECT_FALSE(t.truth.path_free) << "60.5 + 6 m > 60 m";

  // The front at the very end of the approach lane: the light is 0 m ahead (a step into the
  // junction from here enters it on red). Inside the junction, the link it is on is behind.
  t = truth_of(net, trace_route_path(net, kRoute, plan, "A_0", 100, 80), {}, 0.0, ws, j);
  EXPECT_EQ(t.truth.tl_state, kTlRed);
  EXPECT_DOUBLE_EQ(t.truth.tl_distance, 0);
  EXPECT_EQ(t.next_light_state, 'r');
  EXPECT_DOUBLE_EQ(t.next_light_distance, 0);
  EXPECT_EQ(light_at_junction_entry("A_0", ":J_0_0", t.next_light_state, t.next_light_distance),
            kTlRed);
  t = truth_of(net, trace_route_path(net, kRoute, plan, ":J_0_0", 0, 80), {}, 0.0, ws, j);
  EXPECT_EQ(t.truth.tl_state, kTlNone);
  EXPECT_EQ(t.next_light_state, 0);
}

TEST(GroundTruth, PedestriansYieldingAndCommand) {
  const RoadNetwork net = straight_network();
  const LanePlan plan = net.lane_plan(kRoute);
  WorldSettings ws;
  Junction j;
  // The ego's front at 80 m: the junction is 20 m ahead, inside command_horizon.
  const RoutePath near = trace_route_path(net, kRoute, plan, "A_0", 80, 80);
  j.blocked = true;
  j.light = 'r';
  const Actor ped{"ped", Box{{95, 1.0}, 0, 0.5, 0.5}, 0.0, true};
  TruthStep t = truth_of(net, near, {ped}, 0.0, ws, j);
  EXPECT_EQ(t.command, kStraight);
  EXPECT_TRUE(t.truth.must_yield);
  EXPECT_DOUBLE_EQ(t.truth.yield_distance, 20);
  EXPECT_TRUE(t.truth.ped_on_path);
  EXPECT_DOUBLE_EQ(t.truth.ped_distance, 15);
  EXPECT_FALSE(t.truth.lead_present);
  // Standing still, the path-free distance is the margin (6 m): the pedestrian 15 m ahead
  // does not block it.
  EXPECT_DOUBLE_EQ(t.truth.path_free_distance, 6);
  EXPECT_TRUE(t.truth.path_free);
  // A pedestrian 1.75 m beside the lane centre is off the path with the default margin (half
  // the body 0.9 + ped_margin 0.8 = 1.7 m), and on it with a 1 m margin.
  const Actor aside{"ped2", Box{{90, 1.75}, 0, 0.5, 0.5}, 0.0, true};
  EXPECT_FALSE(truth_of(net, near, {aside}, 0.0, ws, j).truth.ped_on_path);
  ws.ped_margin = 1.0;
  EXPECT_TRUE(truth_of(net, near, {aside}, 0.0, ws, j).truth.ped_on_path);
}

// The truth of the pedestrian-corridor tests: the route path of straight_network from the ego's
// front at 52.25 m on A_0, one actor, no light or yield.
GroundTruth truth_beside_path(const Actor& actor, Pose2 ego, double speed, const WorldSettings& ws) {
  const RoadNetwork net = straight_network();
  const RoutePath path = trace_route_path(net, kRoute, net.lane_plan(kRoute), "A_0", 52.25, 80);
  Junction j;
  return truth_of(net, path, {actor}, speed, ws, j, ego).truth;
}

// A free ego's body leaves its path in turns: a pedestrian straight ahead of the body is in its
// way even where it is beside the path (the expert drove into one on town-b-regular task 10,
// trial 1, when it dropped out of the path test for a step).
TEST(GroundTruth, PedestrianAheadOfTheBodyOffThePathIsInTheWay) {
  WorldSettings ws;
  // A pedestrian 2.2 m left of the lane centre, 2.75 m ahead of the front: off the path (the
  // path test reaches 0.9 + 0.8 = 1.7 m beside the centre line).
  const Actor ped{"ped", Box{{55, 2.2}, 0, 0.5, 0.5}, 0.0, true};
  auto truth = [&](Pose2 ego, double speed) { return truth_beside_path(ped, ego, speed, ws); };
  EXPECT_FALSE(truth(Pose2{{50, 0}, 0}, 5.0).ped_on_path);
  // The ego's body 1.2 m left of the centre line (centre at x 50, front at 52.25) at 5 m/s (its
  // corridor: min(8, 1 + 5 * 1.5) = 8 m): the pedestrian is 1.0 m beside its axis, 2.75 m ahead
  // of its front.
  GroundTruth t = truth(Pose2{{50, 1.2}, 0}, 5.0);
  EXPECT_TRUE(t.ped_on_path);
  EXPECT_NEAR(t.ped_distance, 2.75, 1e-9);
  EXPECT_FALSE(t.path_free);
  // At 1 m/s the corridor is 2.5 m: the pedestrian is beyond it. Turned away (heading -0.5
  // rad: 3.3 m beside its axis): off. A shorter ped_ahead_m (2 m) caps it.
  EXPECT_FALSE(truth(Pose2{{50, 1.2}, 0}, 1.0).ped_on_path);
  EXPECT_FALSE(truth(Pose2{{50, 1.2}, -0.5}, 5.0).ped_on_path);
  ws.ped_ahead_m = 2.0;
  EXPECT_FALSE(truth(Pose2{{50, 1.2}, 0}, 5.0).ped_on_path);
}

// A pedestrian standing at the kerb beside a turn waits for the ego to pass (SUMO's walkers
// yield at unprioritised crossings). Straight ahead of the body but off the path, it is in the
// ego's way only within ped_standing_margin (0.3 m) of the body's side, not within ped_margin
// (0.8 m): otherwise each waits for the other (town-b-regular task 13 trial 2, ped31). Walking,
// it keeps the wider band.
TEST(GroundTruth, StandingPedestrianBesideTheBodyOffThePathWaitsForTheEgo) {
  WorldSettings ws;
  const Pose2 ego{{50, 1.2}, 0};  // body 1.2 m left of the centre line, front at 52.25
  auto on = [&](Vec2 at, double speed) {
    const Actor ped{"ped", Box{at, 0, 0.5, 0.5}, speed, true};
    return truth_beside_path(ped, ego, 5.0, ws).ped_on_path;
  };
  // 2.75 m ahead of the front, 1.5 m beside the body's axis (0.6 m from its side), 2.7 m from
  // the centre line (the path test reaches 1.7 m): standing, it is clear (0.9 + 0.3 = 1.2 m);
  // walking along the road at 1 m/s (still 1.5 m beside the axis 1.5 s later), it is not.
  EXPECT_FALSE(on({55, 2.7}, 0.0));
  EXPECT_TRUE(on({55, 2.7}, 1.0));
  // 1.1 m beside the axis (0.2 m from the side): in the way even standing.
  EXPECT_TRUE(on({55, 2.3}, 0.0));
  // The band is the setting: at 0.7 m, the standing pedestrian 1.5 m beside the axis is in it.
  ws.ped_standing_margin = 0.7;
  EXPECT_TRUE(on({55, 2.7}, 0.0));
}

TEST(CauseSchema, RecordedSeriesInFileOrder) {
  const auto& schema = cause_schema();
  std::vector<std::string> names;
  for (const CauseSeries& c : schema) names.push_back(c.name);
  EXPECT_EQ(names.size(), 10u);
  EXPECT_TRUE(std::is_sorted(names.begin(), names.end())) << "HDF5 lists a group's datasets by name";
  GroundTruth none;
  none.tl_state = kTlNone;
  auto value = [&](const std::string& name, const GroundTruth& g) {
    for (const CauseSeries& c : schema)
      if (name == c.name) return c.value(g);
    ADD_FAILURE() << "no series " << name;
    return -1.0;
  };
  EXPECT_EQ(value("lead_distance", none), kAbsentDistance);
  EXPECT_EQ(value("tl_distance", none), kAbsentDistance);
  EXPECT_EQ(value("ped_distance", none), kAbsentDistance);
  EXPECT_EQ(value("path_free", none), 1.0);
  GroundTruth g;
  g.lead_present = true;
  g.lead_distance = 12.5;
  g.tl_state = kTlYellow;
  g.tl_distance = 7;
  EXPECT_EQ(value("lead_distance", g), 12.5);
  EXPECT_EQ(value("lead_present", g), 1.0);
  EXPECT_EQ(value("tl_state", g), 2.0);
  EXPECT_EQ(value("tl_distance", g), 7.0);
}

}  // namespace
}  // namespace cd
