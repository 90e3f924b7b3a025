#pragma once
// Where the ego's footprint lies among the driving lanes, for a free-steering ego
// (ego.lateral = "free", SPEC section 1): off the road (no point of the footprint on any
// driving lane, junction lanes included: the episode ends as `offroad`), driving against the
// direction of the lane it is on (wrong way), across the border of its lane (lane invasion),
// and its lateral and heading error to the centre line of that lane (ground truth). Pure
// geometry on the immutable RoadMap, with a grid so that a city network costs what a town does.
#include <string>
#include <vector>

#include "core/geometry.hpp"
#include "world/road_map.hpp"

namespace cd {

// The driving lanes near each cell of a square grid over the network.
class LaneGrid {
 public:
  explicit LaneGrid(const RoadMap& map, double cell_m = 10.0);
  // Indices (into map.lanes) of the driving lanes whose surface may cover p.
  const std::vector<int>& near(Vec2 p) const;

 private:
  double cell_;
  Vec2 origin_;
  int nx_ = 0, ny_ = 0;
  std::vector<std::vector<int>> cells_;
  std::vector<int> none_;
};

// p against a lane's centre line: the closest point's signed lateral offset (m, left of the
// driving direction positive), the direction of the centre line there (rad) and whether p lies
// on the lane's surface: within width / 2 of the centre line, ends included (round caps).
struct LaneProjection {
  double lateral = 0;
  double direction = 0;
  double along = 0;  // m from the lane's start
  bool on = false;
};
LaneProjection project_on_lane(const LaneGeom& lane, Vec2 p);

struct RoadContact {
  bool offroad = false;        // no point of the footprint (corners, centre) on a driving lane
  bool wrong_way = false;      // the centre is on normal lanes, each against the ego's heading
  bool lane_invasion = false;  // the centre on a normal lane, a corner on neither it nor a
                               // junction lane (across its border)
  int lane = -1;               // the lane the centre is on, best aligned (-1: none)
  double lateral_error = 0;    // m, the centre's offset from that lane's centre line (left +)
  double heading_error = 0;    // rad, ego heading minus that lane's direction, in (-pi, pi]
};

// The footprint (box centre, heading, length, width) against the map.
RoadContact road_contact(const RoadMap& map, const LaneGrid& grid, const Box& footprint);

// An angle in (-pi, pi].
double wrap_angle(double a);

}  // namespace cd
