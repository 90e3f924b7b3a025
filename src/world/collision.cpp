#include "world/collision.hpp"

#include <algorithm>
#include <cmath>

namespace cd {

bool a_strikes(const Box& a, double speed_a, const Box& b, double speed_b) {
  Vec2 u = b.center - a.center;
  const double d = std::sqrt(u.dot(u));
  if (d < 1e-9) return speed_a >= speed_b;
  u = u * (1.0 / d);
  const double closing_a = speed_a * (std::cos(a.heading) * u.x + std::sin(a.heading) * u.y);
  const double closing_b = -speed_b * (std::cos(b.heading) * u.x + std::sin(b.heading) * u.y);
  return closing_a >= closing_b;
}

std::array<Vec2, 4> box_corners(const Box& b) {
  Vec2 f{std::cos(b.heading), std::sin(b.heading)};
  Vec2 l{-f.y, f.x};
  Vec2 hf = f * (b.length / 2), hl = l * (b.width / 2);
  return {b.center + hf + hl, b.center + hf - hl, b.center - hf - hl, b.center - hf + hl};
}

namespace {

// Do the projections of both corner sets on `axis` overlap?
bool overlap_on(Vec2 axis, const std::array<Vec2, 4>& a, const std::array<Vec2, 4>& b) {
  double amin = 1e300, amax = -1e300, bmin = 1e300, bmax = -1e300;
  for (const Vec2& p : a) {
    double d = p.dot(axis);
    amin = std::min(amin, d);
    amax = std::max(amax, d);
  }
  for (const Vec2& p : b) {
    double d = p.dot(axis);
    bmin = std::min(bmin, d);
    bmax = std::max(bmax, d);
  }
  return amax > bmin && bmax > amin;
}

}  // namespace

bool boxes_overlap(const Box& a, const Box& b) {
  double reach = (a.length + a.width + b.length + b.width) / 2;
  if ((a.center - b.center).norm() > reach) return false;
  auto ca = box_corners(a), cb = box_corners(b);
  for (double h : {a.heading, b.heading}) {
    Vec2 f{std::cos(h), std::sin(h)};
    if (!overlap_on(f, ca, cb) || !overlap_on({-f.y, f.x}, ca, cb)) return false;
  }
  return true;
}

Box box_from_front(Vec2 front, double sumo_angle_deg, double length, double width) {
  double h = heading_from_sumo_angle(sumo_angle_deg);
  return {front - Vec2{std::cos(h), std::sin(h)} * (length / 2), h, length, width};
}

}  // namespace cd
