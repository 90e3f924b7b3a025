#include "world/lane_contact.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace cd {

double wrap_angle(double a) {
  a = std::fmod(a + M_PI, 2 * M_PI);
  if (a <= 0) a += 2 * M_PI;
  return a - M_PI;
}

LaneGrid::LaneGrid(const RoadMap& map, double cell_m) : cell_(cell_m) {
  if (map.lanes.empty()) return;
  origin_ = {map.min.x - cell_, map.min.y - cell_};
  nx_ = static_cast<int>(std::ceil((map.max.x - origin_.x) / cell_)) + 2;
  ny_ = static_cast<int>(std::ceil((map.max.y - origin_.y) / cell_)) + 2;
  cells_.assign(static_cast<size_t>(nx_) * ny_, {});
  for (size_t i = 0; i < map.lanes.size(); ++i) {
    const LaneGeom& l = map.lanes[i];
    if (l.kind != LaneKind::Driving) continue;
    const double r = 0.5 * l.width + 0.5;
    for (size_t k = 0; k + 1 < l.shape.size() || (k == 0 && l.shape.size() == 1); ++k) {
      const Vec2 a = l.shape[k], b = l.shape[std::min(k + 1, l.shape.size() - 1)];
      const int x0 = std::max(0, static_cast<int>((std::min(a.x, b.x) - r - origin_.x) / cell_));
      const int x1 = std::min(nx_ - 1, static_cast<int>((std::max(a.x, b.x) + r - origin_.x) / cell_));
      const int y0 = std::max(0, static_cast<int>((std::min(a.y, b.y) - r - origin_.y) / cell_));
      const int y1 = std::min(ny_ - 1, static_cast<int>((std::max(a.y, b.y) + r - origin_.y) / cell_));
      for (int x = x0; x <= x1; ++x)
        for (int y = y0; y <= y1; ++y) {
          std::vector<int>& c = cells_[static_cast<size_t>(y) * nx_ + x];
          if (c.empty() || c.back() != static_cast<int>(i)) c.push_back(static_cast<int>(i));
        }
    }
  }
}

const std::vector<int>& LaneGrid::near(Vec2 p) const {
  const int x = static_cast<int>(std::floor((p.x - origin_.x) / cell_));
  const int y = static_cast<int>(std::floor((p.y - origin_.y) / cell_));
  if (x < 0 || y < 0 || x >= nx_ || y >= ny_) return none_;
  return cells_[static_cast<size_t>(y) * nx_ + x];
}

LaneProjection project_on_lane(const LaneGeom& lane, Vec2 p) {
  LaneProjection best;
  double best_d2 = std::numeric_limits<double>::infinity(), s = 0;
  for (size_t k = 0; k + 1 < lane.shape.size(); ++k) {
    const Vec2 a = lane.shape[k], b = lane.shape[k + 1], ab = b - a;
    const double len2 = ab.dot(ab), len = std::sqrt(len2);
    if (len2 < 1e-12) continue;
    const double t = std::clamp((p - a).dot(ab) / len2, 0.0, 1.0);
    const Vec2 q = a + ab * t, d = p - q;
    const double d2 = d.dot(d);
    if (d2 < best_d2) {
      best_d2 = d2;
      best.direction = std::atan2(ab.y, ab.x);
      best.lateral = ab.cross(p - a) / len;
      best.along = s + t * len;
    }
    s += len;
  }
  // Beyond its ends a lane reaches half its width (a round cap): where a junction lane meets a
  // normal lane at an angle, their caps close the wedge between them.
  best.on = std::sqrt(best_d2) <= 0.5 * lane.width;
  return best;
}

RoadContact road_contact(const RoadMap& map, const LaneGrid& grid, const Box& fp) {
  RoadContact rc;
  const Vec2 f{std::cos(fp.heading), std::sin(fp.heading)}, left{-f.y, f.x};
  const double hl = 0.5 * fp.length, hw = 0.5 * fp.width;
  const Vec2 corners[4] = {fp.center + f * hl + left * hw, fp.center + f * hl - left * hw,
                           fp.center - f * hl - left * hw, fp.center - f * hl + left * hw};

  // The centre: the lane it is on, best aligned with the heading (normal lanes first).
  bool on_normal = false, with_heading = false, centre_on = false;
  double best = std::numeric_limits<double>::infinity();
  for (int i : grid.near(fp.center)) {
    const LaneGeom& l = map.lanes[static_cast<size_t>(i)];
    const LaneProjection pr = project_on_lane(l, fp.center);
    if (!pr.on) continue;
    centre_on = true;
    const double herr = wrap_angle(fp.heading - pr.direction);
    if (!l.internal) {
      on_normal = true;
      with_heading = with_heading || std::abs(herr) <= M_PI / 2;
    }
    // Prefer normal lanes, then the smallest heading error.
    const double score = std::abs(herr) + (l.internal ? 10.0 : 0.0);
    if (score < best) {
      best = score;
      rc.lane = i;
      rc.lateral_error = pr.lateral;
      rc.heading_error = herr;
    }
  }
  rc.wrong_way = on_normal && !with_heading;

  bool any_corner_on = false;
  for (const Vec2& c : corners) {
    // A corner may be on the lane's own surface or inside a junction (entering or leaving
    // it); on another normal lane or off the road it has crossed the lane's border.
    bool on_any = false, on_own_or_junction = false;
    for (int i : grid.near(c)) {
      const LaneGeom& l = map.lanes[static_cast<size_t>(i)];
      if (!project_on_lane(l, c).on) continue;
      on_any = true;
      if (i == rc.lane || l.internal) on_own_or_junction = true;
    }
    any_corner_on = any_corner_on || on_any;
    if (rc.lane >= 0 && !map.lanes[static_cast<size_t>(rc.lane)].internal && !on_own_or_junction)
      rc.lane_invasion = true;
  }
  rc.offroad = !centre_on && !any_corner_on;
  return rc;
}

}  // namespace cd
