#include "render/gl_context.hpp"

#include <GL/osmesa.h>

#include <cstdlib>

#include "core/error.hpp"

namespace cd {

GlContext::GlContext(int width, int height) : width_(width), height_(height) {
  if (width < 1 || height < 1) throw ConfigError("a GL frame needs a positive width and height");
  setenv("LP_NUM_THREADS", "0", 0);
  // Mesa's on-disk shader cache writes from a thread of its own. A worker that made its
  // context and then forks an episode's process (core/worker_pool) would hand the child that
  // queue's lock and condition variable mid-use, without the thread: the child's first shader
  // compile then waits forever (seen: a camera collection hung in pthread_cond_signal). Without
  // the cache the context starts no thread; a shader is compiled once per context instead.
  setenv("MESA_SHADER_CACHE_DISABLE", "true", 1);
  OSMesaContext ctx = OSMesaCreateContextExt(OSMESA_RGBA, 24, 8, 0, nullptr);
  if (ctx == nullptr) throw SimError("cannot create an OSMesa GL context for offscreen rendering");
  ctx_ = ctx;
  buffer_.resize(static_cast<size_t>(width) * height * 4);
  make_current();
}

GlContext::~GlContext() { OSMesaDestroyContext(static_cast<OSMesaContext>(ctx_)); }

void GlContext::make_current() {
  auto ctx = static_cast<OSMesaContext>(ctx_);
  if (OSMesaGetCurrentContext() == ctx) return;
  if (!OSMesaMakeCurrent(ctx, buffer_.data(), GL_UNSIGNED_BYTE, width_, height_))
    throw SimError("cannot make the OSMesa GL context current");
}

void rgb_planes_from_gl_rows(const uint8_t* rows, int stride, int width, int height,
                             uint8_t* out) {
  const size_t plane = static_cast<size_t>(width) * height;
  for (int y = 0; y < height; ++y) {
    const uint8_t* row = rows + static_cast<size_t>(height - 1 - y) * width * stride;
    for (int x = 0; x < width; ++x) {
      const size_t o = static_cast<size_t>(y) * width + x;
      out[o] = row[stride * x];
      out[plane + o] = row[stride * x + 1];
      out[2 * plane + o] = row[stride * x + 2];
    }
  }
}

const uint8_t* GlContext::finish_rgba() {
  make_current();
  glFinish();  // the default framebuffer is our buffer: RGBA, bottom row first
  return buffer_.data();
}

void GlContext::read_rgb_planes(uint8_t* out) {
  rgb_planes_from_gl_rows(finish_rgba(), 4, width_, height_, out);
}

}  // namespace cd
