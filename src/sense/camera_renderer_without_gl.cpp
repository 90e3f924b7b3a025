// The front camera's renderer in a build with neither SUMO nor MuJoCo (CMakeLists.txt), which has
// no GL context (OSMesa comes with either part): constructing one is the one-line MissingPart
// error of core/build_parts.hpp. The other members are never reached; they are defined for the
// linker.
#include "core/build_parts.hpp"
#include "render/gl_context.hpp"
#include "sense/camera.hpp"

namespace cd {

GlContext::~GlContext() = default;

struct CameraRenderer::Ground {};

CameraRenderer::CameraRenderer(const RoadMap&, CameraConfig cfg) : cfg_(std::move(cfg)) {
  require_sumo("the front camera");
  throw MissingPart("no GL context");
}
CameraRenderer::~CameraRenderer() = default;
void CameraRenderer::render(const CameraScene&, uint8_t*) {}

}  // namespace cd
