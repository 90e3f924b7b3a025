#include "world/route_path.hpp"

#include <algorithm>
#include <cmath>

namespace cd {

namespace {

// Calls visit(a, b, len, arc, last) for each segment a -> b of a lane's centre line that has a
// length (len > 0; arc: the lane position where it starts; last: it is the line's last), until
// visit returns true. Returns whether it did.
template <class Visit>
bool walk_segments(const Polyline& shape, Visit visit) {
  double arc = 0;
  for (size_t i = 1; i < shape.size(); ++i) {
    const Vec2 a = shape[i - 1], b = shape[i];
    const double len = (b - a).norm();
    if (len < 1e-9) continue;
    if (visit(a, b, len, arc, i + 1 == shape.size())) return true;
    arc += len;
  }
  return false;
}

}  // namespace

RoutePath trace_route_path(const RoadNetwork& net, const std::vector<std::string>& route,
                           const LanePlan& plan, const std::string& start_lane, double lane_pos,
                           double horizon, const LaneChangeOptions& changes) {
  RoutePath path;
  std::string lane = start_lane;
  double from = lane_pos, steer_from = lane_pos, s = 0;
  size_t k = 0;
  while (!lane.empty() && s < horizon) {
    const LaneGeom* g = net.map.find(lane);
    if (!g) break;
    path.lanes.push_back({g, from, s, 1e300, steer_from, 1e300});
    if (!g->internal && g->edge == route.back()) break;  // the goal lies on this lane
    const std::string next = net.lane_after(route, plan, lane, k);
    const LaneGeom* n = next.empty() ? nullptr : net.map.find(next);
    if (n && !g->internal && !n->internal && n->edge == g->edge) {
      // A lane change: steer off g at `begin` (not before an earlier change has ended), onto n
      // `len` further on. Both lanes of one edge run side by side; a position on one maps to
      // the other by the ratio of their lengths.
      const double len = std::clamp(g->length - steer_from - 1.0, 2.0, changes.length);
      const double ratio = n->length / std::max(g->length, 1e-9);
      double begin = steer_from;
      if (changes.clear && !changes.clear(*n, begin * ratio)) {
        begin = std::max(begin, g->length - len - 1.0);  // as late as the lane allows
        path.hold = std::min(path.hold, s + begin - from);
      }
      PathLane& left = path.lanes.back();
      left.to_pos = begin + len;
      left.steer_to = begin;
      s += begin - from;
      from = std::min(begin * ratio, n->length);
      steer_from = std::min((begin + len) * ratio, n->length);
    } else {
      s += std::max(0.0, g->length - from);
      from = steer_from = 0;
    }
    lane = next;
  }
  for (const PathLane& pl : path.lanes)
    for (const Vec2& q : pl.lane->shape) {
      path.min = {std::min(path.min.x, q.x), std::min(path.min.y, q.y)};
      path.max = {std::max(path.max.x, q.x), std::max(path.max.y, q.y)};
    }
  return path;
}

Vec2 RoutePath::point(double s, Vec2 origin) const {
  Vec2 last = origin, found;
  bool hit = false;
  for (const PathLane& pl : lanes) {
    walk_segments(pl.lane->shape, [&](Vec2 a, Vec2 b, double len, double arc, bool) {
      if (arc >= pl.steer_to) return true;  // the path has left this lane
      const double lo = std::max(arc, pl.steer_from), hi = std::min(arc + len, pl.steer_to);
      if (hi <= lo) return false;
      const double s_lo = pl.s_begin + lo - pl.from_pos, s_hi = pl.s_begin + hi - pl.from_pos;
      if (s <= s_hi) {  // (s below s_lo: within a lane change, the point where it ends)
        found = a + (b - a) * ((std::max(s, s_lo) - pl.s_begin + pl.from_pos - arc) / len);
        hit = true;
        return true;
      }
      last = a + (b - a) * ((hi - arc) / len);
      return false;
    });
    if (hit) return found;
  }
  return last;
}

bool RoutePath::locate(Vec2 p, double half_width, double* s_out) const {
  if (p.x < min.x - half_width || p.x > max.x + half_width || p.y < min.y - half_width ||
      p.y > max.y + half_width)
    return false;
  double best = 1e300;
  for (const PathLane& pl : lanes) {
    if (pl.s_begin >= best) break;  // later lanes are farther along the path
    walk_segments(pl.lane->shape, [&](Vec2 a, Vec2 b, double len, double arc, bool) {
      const Vec2 u = (b - a) * (1.0 / len);
      const double along = (p - a).dot(u);
      const double lat = std::abs((p - a).cross(u));
      if (along >= -0.5 && along <= len + 0.5 && lat <= half_width) {
        const double lane_pos = arc + std::clamp(along, 0.0, len);
        if (lane_pos >= pl.from_pos - 0.01 && lane_pos <= pl.to_pos + 0.01)
          best = std::min(best, pl.s_begin + lane_pos - pl.from_pos);
      }
      return false;
    });
  }
  if (best >= 1e300) return false;
  *s_out = best;
  return true;
}

std::optional<std::pair<Vec2, Vec2>> RoutePath::line_across(double s) const {
  for (const PathLane& pl : lanes) {
    if (s > pl.s_begin + std::min(pl.lane->length, pl.to_pos) - pl.from_pos + 1e-6) continue;
    const double target = pl.from_pos + (s - pl.s_begin), hw = pl.lane->width / 2;
    std::optional<std::pair<Vec2, Vec2>> line;
    walk_segments(pl.lane->shape, [&](Vec2 a, Vec2 b, double len, double arc, bool last) {
      if (arc + len < target - 1e-6 && !last) return false;
      const Vec2 u = (b - a) * (1.0 / len);
      const Vec2 q = a + u * std::clamp(target - arc, 0.0, len);
      const Vec2 n{-u.y, u.x};
      line = std::make_pair(q + n * hw, q - n * hw);
      return true;
    });
    return line;
  }
  return std::nullopt;
}

}  // namespace cd
