#pragma once
// Headless offscreen rendering: the GL context of render/gl_context (OSMesa, no display, no
// window), MuJoCo's render context on it, and its offscreen framebuffer sized to the frame.
#include <cstdint>
#include <vector>

#include <mujoco/mujoco.h>

#include "mujoco/env_spec.hpp"
#include "render/gl_context.hpp"

namespace cd::mj {

class OffscreenRenderer {
 public:
  // Throws SimError when no GL context can be made.
  OffscreenRenderer(const mjModel& model, int width, int height);
  ~OffscreenRenderer();
  OffscreenRenderer(const OffscreenRenderer&) = delete;
  OffscreenRenderer& operator=(const OffscreenRenderer&) = delete;

  // Draws the state of `data` from `camera` into out: 3 x height x width bytes, RGB planes,
  // top row first.
  void render(const mjModel& model, mjData& data, const CameraSpec& camera, uint8_t* out);

 private:
  int width_, height_;
  GlContext gl_;              // its default framebuffer is unused: MuJoCo draws into its own
  std::vector<uint8_t> rgb_;  // interleaved, bottom row first, as read back
  mjvScene scene_;
  mjvOption option_;
  mjrContext context_;
};

}  // namespace cd::mj
