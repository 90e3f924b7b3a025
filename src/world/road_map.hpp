#pragma once
// Immutable lane geometry of one road network, read once and shared by the rasteriser,
// the expert and the checks (the MuJoCo mjModel role).
#include <string>
#include <unordered_map>
#include <vector>

#include "core/geometry.hpp"

namespace cd {

enum class LaneKind {
  Driving,      // a lane cars may use (normal or inside a junction)
  Sidewalk,     // pedestrians only, along an edge
  Crossing,     // pedestrian crossing inside a junction
  WalkingArea,  // pedestrian area at a junction corner
};

struct LaneGeom {
  std::string id;       // SUMO lane id, e.g. "A0B0_1" or ":B0_3_0"
  std::string edge;     // SUMO edge id
  LaneKind kind = LaneKind::Driving;
  bool internal = false;  // inside a junction (id starts with ':')
  int index = 0;          // lane index within its edge (0 = rightmost)
  double width = 3.2;
  double length = 0;
  Polyline shape;  // centre line in driving direction
  // Only for normal driving lanes: does a driving lane of the same edge lie to the left
  // (then the left border is a dashed lane divider) and to the right.
  bool has_left_neighbour = false;
  bool has_right_neighbour = false;
};

struct RoadMap {
  std::vector<LaneGeom> lanes;
  std::unordered_map<std::string, int> lane_index;  // lane id -> index into lanes
  Vec2 min{1e300, 1e300}, max{-1e300, -1e300};  // bounding box of all lane shapes

  const LaneGeom* find(const std::string& lane_id) const {
    auto it = lane_index.find(lane_id);
    return it == lane_index.end() ? nullptr : &lanes[it->second];
  }
  void add(LaneGeom lane);  // appends, indexes and grows the bounding box
};

}  // namespace cd
