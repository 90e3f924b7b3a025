#include "world/road_network.hpp"

namespace cd {

const LaneGeom& RoadNetwork::rightmost_lane(const std::string& edge) const {
  return map.lanes[static_cast<size_t>(edge_lane.at(edge))];
}

const ViaInfo* RoadNetwork::find_via(const std::string& via) const {
  auto it = via_info.find(via);
  return it == via_info.end() ? nullptr : &it->second;
}

const std::string& RoadNetwork::via_of(const std::string& internal_lane) const {
  auto it = via_head.find(internal_lane);
  return it == via_head.end() ? internal_lane : it->second;
}

const std::vector<std::string>& RoadNetwork::foes_of(const std::string& internal_lane) const {
  static const std::vector<std::string> none;
  auto it = internal_foes.find(internal_lane);
  return it == internal_foes.end() ? none : it->second;
}

std::string RoadNetwork::next_lane(const std::string& lane, const std::string& to_edge,
                                   const std::unordered_set<std::string>* good) const {
  auto it = links.find(lane);
  if (it == links.end()) return "";
  std::string fallback;
  for (const Link& l : it->second) {
    const LaneGeom* to = map.find(l.to_lane);
    if (!to || to->edge != to_edge) continue;
    std::string next = l.via_lane.empty() ? l.to_lane : l.via_lane;
    if (!good || good->count(l.to_lane)) return next;
    if (fallback.empty()) fallback = next;
  }
  return fallback;
}

LanePlan RoadNetwork::lane_plan(const std::vector<std::string>& route) const {
  // Computed from the goal backwards.
  LanePlan good(route.size());
  for (size_t k = route.size(); k-- > 0;) {
    auto it = edge_lanes.find(route[k]);
    if (it == edge_lanes.end()) break;
    for (const std::string& lane : it->second) {
      if (k + 1 == route.size()) {
        good[k].insert(lane);
        continue;
      }
      auto lit = links.find(lane);
      if (lit == links.end()) continue;
      for (const Link& l : lit->second)
        if (good[k + 1].count(l.to_lane)) good[k].insert(lane);
    }
  }
  return good;
}

std::string RoadNetwork::lane_after(const std::vector<std::string>& route, const LanePlan& plan,
                                    const std::string& lane, size_t& k) const {
  const LaneGeom* g = map.find(lane);
  if (!g) return "";
  if (g->internal) {
    auto it = links.find(lane);
    if (it == links.end() || it->second.empty()) return "";
    const Link& l = it->second.front();
    return l.via_lane.empty() ? l.to_lane : l.via_lane;
  }
  while (k < route.size() && route[k] != g->edge) ++k;
  if (k + 1 >= route.size()) return "";
  return next_lane(lane, route[k + 1], k + 1 < plan.size() ? &plan[k + 1] : nullptr);
}

std::string RoadNetwork::first_via(const std::vector<std::string>& route, int start_lane) const {
  if (route.size() < 2 || start_lane < 0) return "";
  const LanePlan plan = lane_plan(route);
  const std::string lane = route[0] + "_" + std::to_string(start_lane);
  return next_lane(lane, route[1], &plan[1]);
}

}  // namespace cd
