#include "mujoco/renderer.hpp"

#include <GL/osmesa.h>

#include <cmath>
#include <cstdlib>
#include <string>

#include "core/error.hpp"

namespace cd::mj {

namespace {

constexpr int kMaxGeoms = 2000;

}  // namespace

OffscreenRenderer::OffscreenRenderer(const mjModel& model, int width, int height)
    : width_(width), height_(height) {
  // llvmpipe draws in the calling thread when asked to: a 64x64 frame gains nothing from
  // threads, the trainer beside us keeps its cores, and a forked worker inherits no thread.
  setenv("LP_NUM_THREADS", "0", 0);
  OSMesaContext ctx = OSMesaCreateContextExt(OSMESA_RGBA, 24, 8, 0, nullptr);
  if (ctx == nullptr) throw SimError("cannot create an OSMesa GL context for offscreen rendering");
  gl_ = ctx;
  gl_buffer_.resize(static_cast<size_t>(width) * height * 4);
  make_current();

  // MuJoCo sizes its offscreen framebuffer from the model: a copy asks for exactly our frame.
  mjModel* sized = mj_copyModel(nullptr, &model);
  if (sized == nullptr) throw SimError("cannot copy the MuJoCo model for rendering");
  sized->vis.global.offwidth = width;
  sized->vis.global.offheight = height;
  mjv_defaultScene(&scene_);
  mjv_defaultOption(&option_);
  mjr_defaultContext(&context_);
  mjv_makeScene(&model, &scene_, kMaxGeoms);
  mjr_makeContext(sized, &context_, mjFONTSCALE_100);
  mj_deleteModel(sized);
  if (context_.offFBO == 0) {
    mjr_freeContext(&context_);
    mjv_freeScene(&scene_);
    OSMesaDestroyContext(ctx);
    throw SimError("MuJoCo could not create its offscreen framebuffer on the OSMesa context");
  }
  mjr_setBuffer(mjFB_OFFSCREEN, &context_);
  rgb_.resize(static_cast<size_t>(width) * height * 3);
}

OffscreenRenderer::~OffscreenRenderer() {
  make_current();
  mjr_freeContext(&context_);
  mjv_freeScene(&scene_);
  OSMesaDestroyContext(static_cast<OSMesaContext>(gl_));
}

void OffscreenRenderer::make_current() {
  auto ctx = static_cast<OSMesaContext>(gl_);
  if (OSMesaGetCurrentContext() == ctx) return;
  if (!OSMesaMakeCurrent(ctx, gl_buffer_.data(), GL_UNSIGNED_BYTE, width_, height_))
    throw SimError("cannot make the OSMesa GL context current");
}

void OffscreenRenderer::render(const mjModel& model, mjData& data, const CameraSpec& spec,
                               uint8_t* out) {
  make_current();
  mjvCamera cam;
  mjv_defaultCamera(&cam);
  cam.type = mjCAMERA_FREE;  // we move the look-at point ourselves
  cam.distance = spec.distance;
  cam.azimuth = spec.azimuth;
  cam.elevation = spec.elevation;
  for (int i = 0; i < 3; ++i) cam.lookat[i] = spec.lookat[i];
  if (spec.track_body >= 0 && spec.track_body < model.nbody) {
    const mjtNum* com = data.subtree_com + 3 * spec.track_body;
    cam.lookat[0] = com[0];
    cam.lookat[1] = com[1];
    if (!spec.fixed_height) cam.lookat[2] = com[2];
  }
  mjv_updateScene(&model, &data, &option_, nullptr, &cam, mjCAT_ALL, &scene_);
  mjr_setBuffer(mjFB_OFFSCREEN, &context_);
  const mjrRect viewport = {0, 0, width_, height_};
  mjr_render(viewport, &scene_, &context_);
  mjr_readPixels(rgb_.data(), nullptr, viewport, &context_);
  // Interleaved RGB, bottom row first -> RGB planes, top row first.
  const size_t plane = static_cast<size_t>(width_) * height_;
  for (int y = 0; y < height_; ++y) {
    const uint8_t* row = rgb_.data() + static_cast<size_t>(height_ - 1 - y) * width_ * 3;
    for (int x = 0; x < width_; ++x) {
      const size_t o = static_cast<size_t>(y) * width_ + x;
      out[o] = row[3 * x];
      out[plane + o] = row[3 * x + 1];
      out[2 * plane + o] = row[3 * x + 2];
    }
  }
}

}  // namespace cd::mj
