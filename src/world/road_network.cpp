#include "world/road_network.hpp"

#include <cstdlib>

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
    std::unordered_set<std::string> reach_next;  // lanes with any connection to edge k+1
    for (const std::string& lane : it->second) {
      if (k + 1 == route.size()) {
        good[k].insert(lane);
        continue;
      }
      auto lit = links.find(lane);
      if (lit == links.end()) continue;
      for (const Link& l : lit->second) {
        const LaneGeom* to = map.find(l.to_lane);
        if (to && to->edge == route[k + 1]) reach_next.insert(lane);
        if (good[k + 1].count(l.to_lane)) good[k].insert(lane);
      }
    }
    if (good[k].empty()) good[k] = std::move(reach_next);
  }
  return good;
}

std::string RoadNetwork::change_lane(const LanePlan& plan, const std::string& lane,
                                     size_t k) const {
  const LaneGeom* g = map.find(lane);
  if (!g || g->internal || k >= plan.size() || plan[k].empty() || plan[k].count(lane)) return "";
  int best = -1;  // the planned lane index nearest to g's
  for (const std::string& p : plan[k]) {
    const LaneGeom* q = map.find(p);
    if (q && (best < 0 || std::abs(q->index - g->index) < std::abs(best - g->index)))
      best = q->index;
  }
  if (best < 0) return "";
  const int step = best > g->index ? 1 : -1;
  auto it = edge_lanes.find(g->edge);
  if (it == edge_lanes.end()) return "";
  for (const std::string& n : it->second) {
    const LaneGeom* q = map.find(n);
    if (q && q->index == g->index + step) return n;
  }
  return "";
}

std::vector<LaneChange> RoadNetwork::lane_changes(const std::vector<std::string>& route,
                                                  int start_lane) const {
  std::vector<LaneChange> changes;
  if (route.empty() || start_lane < 0) return changes;
  const LanePlan plan = lane_plan(route);
  std::string lane = route.front() + "_" + std::to_string(start_lane), edge = route.front();
  size_t k = 0;
  for (int guard = 0; !lane.empty() && guard < 100000; ++guard) {
    const std::string next = lane_after(route, plan, lane, k);
    const LaneGeom *g = map.find(lane), *n = map.find(next);
    if (g && n && !g->internal && !n->internal && g->edge == n->edge)
      changes.push_back({lane, next});
    lane = next;
  }
  return changes;
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
  if (std::string side = change_lane(plan, lane, k); !side.empty()) return side;
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
