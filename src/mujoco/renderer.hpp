#pragma once
// Headless offscreen rendering: an OSMesa GL context of our own (no display, no window), MuJoCo's
// render context on it, and its offscreen framebuffer sized to the frame.
#include <cstdint>
#include <vector>

#include <mujoco/mujoco.h>

#include "mujoco/env_spec.hpp"

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
  void make_current();

  int width_, height_;
  void* gl_ = nullptr;  // OSMesaContext
  std::vector<uint8_t> gl_buffer_;  // the context's default framebuffer (unused by MuJoCo)
  std::vector<uint8_t> rgb_;        // interleaved, bottom row first, as read back
  mjvScene scene_;
  mjvOption option_;
  mjrContext context_;
};

}  // namespace cd::mj
