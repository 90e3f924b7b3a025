#pragma once
// The one headless GL context of causaldrive (SPEC section 16): an OSMesa context with its own
// RGBA framebuffer and a depth buffer, no display and no window. MuJoCo-Image's renderer draws
// on it through MuJoCo's offscreen framebuffer; the driving world's front camera draws on its
// default framebuffer and reads it back here.
#include <cstdint>
#include <vector>

namespace cd {

// Interleaved pixels of `stride` bytes (RGB or RGBA), bottom row first as GL reads them, into
// RGB planes, top row first: 3 x height x width bytes.
void rgb_planes_from_gl_rows(const uint8_t* rows, int stride, int width, int height, uint8_t* out);

class GlContext {
 public:
  // Throws SimError when no context can be made. llvmpipe draws in the calling thread
  // (LP_NUM_THREADS=0 unless the environment says otherwise): a small frame gains nothing from
  // threads, the trainer beside us keeps its cores, and the bytes of a frame do not depend on a
  // thread count. Mesa's shader cache on disk is off (MESA_SHADER_CACHE_DISABLE, set always):
  // it runs a thread, and a process holding a context must fork safely (core/worker_pool
  // forks each episode from a worker that made its world), so a context starts no thread.
  GlContext(int width, int height);
  ~GlContext();
  GlContext(const GlContext&) = delete;
  GlContext& operator=(const GlContext&) = delete;

  // Makes this context current in the calling thread (a no-op when it is).
  void make_current();
  // The default framebuffer's pixels as RGB planes, top row first: 3 x height x width bytes.
  void read_rgb_planes(uint8_t* out);
  // The default framebuffer when GL has finished drawing: RGBA, bottom row first (valid until
  // the next call that draws).
  const uint8_t* finish_rgba();

  int width() const { return width_; }
  int height() const { return height_; }

 private:
  int width_, height_;
  void* ctx_ = nullptr;           // OSMesaContext
  std::vector<uint8_t> buffer_;   // the default framebuffer, RGBA, bottom row first
};

}  // namespace cd
