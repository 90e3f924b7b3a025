#pragma once
// Oriented-box overlap (separating axis test): SUMO checks collisions per lane, so the World
// adds this test against every actor near the ego.
#include <array>

#include "core/geometry.hpp"

namespace cd {

std::array<Vec2, 4> box_corners(const Box& b);
bool boxes_overlap(const Box& a, const Box& b);

// Who struck whom in a collision of a and b: a did when it closes on b at least as fast as b
// closes on a, along the line between their centres (speed in m/s along each one's heading).
// A car running into a stopped one, into a pedestrian or into another's side is the striker;
// a car rear-ended while stopped was struck.
bool a_strikes(const Box& a, double speed_a, const Box& b, double speed_b);

// The box of a SUMO vehicle from its front-bumper position and compass angle.
Box box_from_front(Vec2 front, double sumo_angle_deg, double length, double width);

}  // namespace cd
