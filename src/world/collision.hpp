#pragma once
// Oriented-box overlap (separating axis test): SUMO checks collisions per lane, so the World
// adds this test against every actor near the ego.
#include <array>

#include "core/geometry.hpp"

namespace cd {

std::array<Vec2, 4> box_corners(const Box& b);
bool boxes_overlap(const Box& a, const Box& b);

// The box of a SUMO vehicle from its front-bumper position and compass angle.
Box box_from_front(Vec2 front, double sumo_angle_deg, double length, double width);

}  // namespace cd
