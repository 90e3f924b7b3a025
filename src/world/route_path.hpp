#pragma once
// The ego's path: the lanes of its route ahead of its front bumper, with distances along the
// path. Pure geometry over the road network (no simulator): where a point lies along the
// path, the point s metres ahead, the stop line at a distance.
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "core/geometry.hpp"
#include "world/road_network.hpp"

namespace cd {

// One lane of the path. Across a lane change the lane left and its neighbour overlap over the
// stretch of the change (both hold what is on the path there: locate); the line to steer along
// (point) leaves the first where the change begins and joins the second where it ends, so the
// driver steers the diagonal between them.
struct PathLane {
  const LaneGeom* lane = nullptr;
  double from_pos = 0;        // lane position where the path enters this lane
  double s_begin = 0;         // distance along the path (from the ego's front) of from_pos
  double to_pos = 1e300;      // lane position where it leaves the lane (end, or change's end)
  double steer_from = 0;      // lane positions of the stretch to steer along (>= from_pos,
  double steer_to = 1e300;    // <= to_pos)
};

// Lane changes on the path: it leaves a lane at s = begin and joins its neighbour at
// begin + length.
struct LaneChangeOptions {
  double length = 20.0;  // m along the lanes that a change takes
  // Whether a change into `to` at lane position `pos` may begin now (traffic); when it may
  // not, the change begins as late as the lane allows and `hold` marks where.
  std::function<bool(const LaneGeom& to, double pos)> clear;
};

struct RoutePath {
  std::vector<PathLane> lanes;
  // Distance along the path to where a lane change that may not begin yet must begin (the
  // driver waits there); 1e300 when there is none.
  double hold = 1e300;
  Vec2 min{1e300, 1e300}, max{-1e300, -1e300};  // bounding box of the path's lane shapes

  // The point `s` metres along the path, or the path's last point when it is shorter
  // (`origin` when the path is empty).
  Vec2 point(double s, Vec2 origin) const;
  // Does p lie within half_width of the path's centre line? Then *s is its distance along
  // the path (the nearest one, on the first lane that holds it).
  bool locate(Vec2 p, double half_width, double* s) const;
  // The stop line across the path `s` metres ahead (its two ends, lane width apart), if the
  // path reaches that far.
  std::optional<std::pair<Vec2, Vec2>> line_across(double s) const;
};

// The path from lane position `lane_pos` of `lane` along `route` (plan: its lane plan), up to
// `horizon` metres or the lane holding the goal, through the lane changes the plan needs.
RoutePath trace_route_path(const RoadNetwork& net, const std::vector<std::string>& route,
                           const LanePlan& plan, const std::string& lane, double lane_pos,
                           double horizon, const LaneChangeOptions& changes = {});

}  // namespace cd
