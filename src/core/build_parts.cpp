#include "core/build_parts.hpp"

// CMakeLists.txt defines these for this file alone.
#ifndef CD_HAS_SUMO
#define CD_HAS_SUMO 1
#endif
#ifndef CD_HAS_MUJOCO
#define CD_HAS_MUJOCO 1
#endif
#ifndef CD_HAS_TORCH_CUDA
#define CD_HAS_TORCH_CUDA 0
#endif

namespace cd {

bool built_with_sumo() { return CD_HAS_SUMO != 0; }
bool built_with_mujoco() { return CD_HAS_MUJOCO != 0; }
bool torch_built_with_cuda() { return CD_HAS_TORCH_CUDA != 0; }

namespace {

void require(bool have, const std::string& part, const std::string& option,
             const std::string& what) {
  if (have) return;
  throw MissingPart(what + " needs " + part + ", which this build leaves out (configured with -D" +
                    option + "=OFF); install it (scripts/setup.sh) and rebuild with -D" + option +
                    "=ON");
}

}  // namespace

void require_sumo(const std::string& what) {
  require(built_with_sumo(), "SUMO", "CD_WITH_SUMO", what);
}

void require_mujoco(const std::string& what) {
  require(built_with_mujoco(), "MuJoCo", "CD_WITH_MUJOCO", what);
}

std::string build_parts_description() {
  return std::string("SUMO: ") + (built_with_sumo() ? "yes" : "no") +
         ", MuJoCo: " + (built_with_mujoco() ? "yes" : "no");
}

}  // namespace cd
