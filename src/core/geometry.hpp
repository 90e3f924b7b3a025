#pragma once
// Planar geometry in SUMO's network frame (metres, x east, y north).
#include <algorithm>
#include <cmath>
#include <vector>

namespace cd {

struct Vec2 {
  double x = 0, y = 0;
  Vec2 operator+(Vec2 o) const { return {x + o.x, y + o.y}; }
  Vec2 operator-(Vec2 o) const { return {x - o.x, y - o.y}; }
  Vec2 operator*(double s) const { return {x * s, y * s}; }
  double dot(Vec2 o) const { return x * o.x + y * o.y; }
  double cross(Vec2 o) const { return x * o.y - y * o.x; }
  double norm() const { return std::hypot(x, y); }
};

// Heading in radians, mathematical convention: 0 = east (+x), counter-clockwise positive.
struct Pose2 {
  Vec2 pos;
  double heading = 0;
};

// Point p (network frame) in the frame of `ego`: x forward along its heading, y to its left.
inline Vec2 to_ego_frame(const Pose2& ego, Vec2 p) {
  const double c = std::cos(ego.heading), s = std::sin(ego.heading);
  const Vec2 d = p - ego.pos;
  return {c * d.x + s * d.y, -s * d.x + c * d.y};
}

// `pose` moved `shift` m to its left and turned by `turn` rad: the pose a frame of the lateral
// augmentation (collect.augment) is rendered from, and the frame its labels are expressed in.
inline Pose2 shifted_pose(const Pose2& pose, double shift, double turn) {
  return {pose.pos + Vec2{-std::sin(pose.heading), std::cos(pose.heading)} * shift,
          pose.heading + turn};
}

// SUMO reports compass degrees (0 = north, clockwise); convert to our heading.
inline double heading_from_sumo_angle(double deg) {
  return (90.0 - deg) * M_PI / 180.0;
}

// An oriented rectangle: centre, heading of its length axis, full length and width.
struct Box {
  Vec2 center;
  double heading = 0;
  double length = 0;
  double width = 0;
};

using Polyline = std::vector<Vec2>;

inline double polyline_length(const Polyline& p) {
  double s = 0;
  for (size_t i = 1; i < p.size(); ++i) s += (p[i] - p[i - 1]).norm();
  return s;
}

// The point `ahead` metres along a polyline from the projection of `from` onto it (beyond its
// end, along its last segment). A path tracker's target on a planned path.
inline Vec2 point_along_polyline(const Polyline& line, Vec2 from, double ahead) {
  if (line.empty()) return from;
  size_t best = 0;
  double best_d2 = 1e300, best_t = 0;
  for (size_t k = 0; k + 1 < line.size(); ++k) {
    const Vec2 ab = line[k + 1] - line[k];
    const double len2 = ab.dot(ab);
    const double t = len2 > 1e-12 ? std::clamp((from - line[k]).dot(ab) / len2, 0.0, 1.0) : 0.0;
    const Vec2 d = from - (line[k] + ab * t);
    if (d.dot(d) < best_d2) best_d2 = d.dot(d), best = k, best_t = t;
  }
  double left = ahead;
  for (size_t k = best; k + 1 < line.size(); ++k) {
    const Vec2 a = k == best ? line[k] + (line[k + 1] - line[k]) * best_t : line[k];
    const Vec2 ab = line[k + 1] - a;
    const double len = ab.norm();
    if (len >= left || k + 2 == line.size()) return len > 1e-9 ? a + ab * (left / len) : a;
    left -= len;
  }
  return line.back();
}

// Road markings, shared by the bird's-eye view and the front camera. Dashes are centred on
// multiples of the period along s, so the pattern is symmetric under s -> -s: the two opposite
// lanes that share a centre line (directions d and -d) paint the same dashes without having to
// agree on a canonical direction.
inline bool dash_painted(double s, double dash, double period) {
  double m = std::fmod(s + 0.5 * dash, period);
  if (m < 0) m += period;
  return m < dash;
}

inline Polyline without_repeats(const Polyline& in) {
  Polyline out;
  for (const Vec2& p : in)
    if (out.empty() || (p - out.back()).norm() > 1e-9) out.push_back(p);
  return out;
}

// The polyline (at least 2 points, no repeats) moved `offset` metres to its left (negative:
// right), with mitred joints so consecutive offset segments meet; the miter is capped at 4x the
// offset at hairpins.
inline Polyline offset_polyline(const Polyline& pts, double offset) {
  std::vector<Vec2> normal(pts.size() - 1);
  for (size_t i = 0; i + 1 < pts.size(); ++i) {
    Vec2 d = pts[i + 1] - pts[i];
    normal[i] = Vec2{-d.y, d.x} * (1.0 / d.norm());
  }
  Polyline out(pts.size());
  out.front() = pts.front() + normal.front() * offset;
  out.back() = pts.back() + normal.back() * offset;
  for (size_t i = 1; i + 1 < pts.size(); ++i) {
    Vec2 m = normal[i - 1] + normal[i];
    double len = m.norm();
    if (len < 1e-6) {
      out[i] = pts[i] + normal[i] * offset;
      continue;
    }
    m = m * (1.0 / len);
    out[i] = pts[i] + m * (offset / std::max(m.dot(normal[i]), 0.25));
  }
  return out;
}

}  // namespace cd
