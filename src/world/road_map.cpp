#include "world/road_map.hpp"

#include <algorithm>

namespace cd {

void RoadMap::add(LaneGeom lane) {
  for (const Vec2& p : lane.shape) {
    min.x = std::min(min.x, p.x);
    min.y = std::min(min.y, p.y);
    max.x = std::max(max.x, p.x);
    max.y = std::max(max.y, p.y);
  }
  lane_index[lane.id] = static_cast<int>(lanes.size());
  lanes.push_back(std::move(lane));
}

}  // namespace cd
