#pragma once
// The pixel convention of sense/camera.hpp for code that already holds a camera's frame (the
// renderer projects every solid's vertex of a frame with one CameraFrame). camera_project() is
// this with the frame of an ego's pose. Its own header, so that only the camera's two sources
// include it.
#include <optional>

#include "sense/camera.hpp"

namespace cd {

// Where the network-frame point p lands for the camera frame f; nullopt when it lies nearer
// than near_m along the view axis (behind the near plane).
std::optional<PixelPoint> camera_project(const CameraFrame& f, double near_m, Vec3 p);

}  // namespace cd
