#include "mujoco/renderer.hpp"

#include <cmath>
#include <cstdlib>
#include <string>

#include "core/error.hpp"

namespace cd::mj {

namespace {

constexpr int kMaxGeoms = 2000;

}  // namespace

OffscreenRenderer::OffscreenRenderer(const mjModel& model, int width, int height)
    : width_(width), height_(height), gl_(width, height) {
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
    throw SimError("MuJoCo could not create its offscreen framebuffer on the OSMesa context");
  }
  mjr_setBuffer(mjFB_OFFSCREEN, &context_);
  rgb_.resize(static_cast<size_t>(width) * height * 3);
}

OffscreenRenderer::~OffscreenRenderer() {
  gl_.make_current();
  mjr_freeContext(&context_);
  mjv_freeScene(&scene_);
}

void OffscreenRenderer::render(const mjModel& model, mjData& data, const CameraSpec& spec,
                               uint8_t* out) {
  gl_.make_current();
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
  rgb_planes_from_gl_rows(rgb_.data(), 3, width_, height_, out);
}

}  // namespace cd::mj
