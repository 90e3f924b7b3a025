#pragma once
// The immutable road network of one town (MuJoCo's mjModel role): lane geometry, junction
// topology (links, the connection each internal lane belongs to, its light, its foes) and the
// lane-level route planning on them. Built once from the simulator when a World starts
// (world/world.cpp) and shared read-only; everything declared here is pure, so tests can build
// a network by hand and call it without SUMO.
#include <string>
#include <unordered_map>
#include <unordered_set>
#include <vector>

#include "world/road_map.hpp"

namespace cd {

// A connection from a lane to the next one, through an internal lane (the via) when it
// crosses a junction.
struct Link {
  std::string to_lane, via_lane;
  char direction = 's';  // SUMO's s, l, r, t, ...
};

// A connection through a junction, keyed by its first internal lane (the via).
struct ViaInfo {
  std::string approach;    // the normal lane it leaves from
  char direction = 's';    // SUMO's s, l, r, ...
  char fixed_state = 'O';  // state of an unsignalised link (M, m, =, ...)
  std::string tls;         // the light controlling it, if any
  int tls_index = -1;      // its index in that light's state string
};

// Per route edge k, the lanes of edge k to drive on: those from which the rest of the route is
// drivable without a lane change when there are any; else those with a connection to edge k+1
// (a lane change on a later edge is then unavoidable). A lane of edge k outside the set is left
// by a lane change towards it (RoadNetwork::change_lane).
using LanePlan = std::vector<std::unordered_set<std::string>>;

// A lane change along a route: from a lane to its neighbour on the same edge.
struct LaneChange {
  std::string from, to;
};

struct RoadNetwork {
  std::string path;  // the .net.xml it was read from
  RoadMap map;
  std::unordered_map<std::string, std::vector<Link>> links;  // lane -> outgoing links
  std::unordered_map<std::string, ViaInfo> via_info;         // via lane -> its connection
  std::unordered_map<std::string, std::string> via_head;     // internal lane -> its via
  std::unordered_map<std::string, std::vector<std::string>> internal_foes;  // internal lane
  std::unordered_map<std::string, int> edge_lane;  // car edge -> its rightmost car lane (index)
  std::unordered_map<std::string, std::vector<std::string>> edge_lanes;  // car edge -> lanes
  std::unordered_map<std::string, size_t> sidewalk_of_edge;  // edge -> its sidewalk lane
  std::vector<std::string> car_edges;  // normal edges with a lane for cars, sorted
  std::vector<std::string> ped_edges;  // normal edges with a sidewalk, sorted
  double lane_km = 0;                  // km of driving lane (traffic scales with it)

  // The rightmost car lane of a car edge (insertion positions, lengths).
  const LaneGeom& rightmost_lane(const std::string& edge) const;
  const ViaInfo* find_via(const std::string& via) const;  // nullptr for other lanes
  // The via of the connection an internal lane belongs to (the lane itself otherwise).
  const std::string& via_of(const std::string& internal_lane) const;
  const std::vector<std::string>& foes_of(const std::string& internal_lane) const;

  LanePlan lane_plan(const std::vector<std::string>& route) const;
  // The lane of `to_edge` reached from `lane` (its via lane when it has one), preferring
  // lanes in `good`; "" when there is no connection.
  std::string next_lane(const std::string& lane, const std::string& to_edge,
                        const std::unordered_set<std::string>* good) const;
  // The lane after `lane` along `route` (plan: lane_plan(route)); k tracks the route edge
  // index across calls. "" at the route's end. For a normal lane outside the plan this is its
  // neighbour towards the plan on the same edge (a lane change: change_lane).
  std::string lane_after(const std::vector<std::string>& route, const LanePlan& plan,
                         const std::string& lane, size_t& k) const;
  // The neighbour (same edge, index one step towards the plan's nearest lane) that a normal
  // lane of route edge k outside plan[k] changes to; "" when the lane is in the plan (or is
  // internal, or the edge has no planned lane).
  std::string change_lane(const LanePlan& plan, const std::string& lane, size_t k) const;
  // The lane changes of a drive along `route` from lane index start_lane of its first edge, in
  // order (empty: the route is drivable without changing lanes).
  std::vector<LaneChange> lane_changes(const std::vector<std::string>& route,
                                       int start_lane) const;
  // The first link of a route from lane start_lane of its first edge: its via lane ("" if
  // none).
  std::string first_via(const std::vector<std::string>& route, int start_lane) const;
};

}  // namespace cd
