#pragma once
// The ego's path: the lanes of its route ahead of its front bumper, with distances along the
// path. Pure geometry over the road network (no simulator): where a point lies along the
// path, the point s metres ahead, the stop line at a distance.
#include <optional>
#include <string>
#include <vector>

#include "core/geometry.hpp"
#include "world/road_network.hpp"

namespace cd {

struct PathLane {
  const LaneGeom* lane = nullptr;
  double from_pos = 0;  // lane position where the path enters this lane
  double s_begin = 0;   // distance along the path (from the ego's front) of from_pos
};

struct RoutePath {
  std::vector<PathLane> lanes;
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
// `horizon` metres or the lane holding the goal.
RoutePath trace_route_path(const RoadNetwork& net, const std::vector<std::string>& route,
                           const LanePlan& plan, const std::string& lane, double lane_pos,
                           double horizon);

}  // namespace cd
