#pragma once
// The optional parts of a build (SPEC section 11, CMakeLists.txt: CD_WITH_SUMO, CD_WITH_MUJOCO)
// and whether this libtorch was built with CUDA. A build without a part still trains every
// method on recorded data; what needs the part throws MissingPart, one line naming the part, the
// command and how to get it.
#include <string>

#include "core/error.hpp"

namespace cd {

struct MissingPart : ConfigError {
  using ConfigError::ConfigError;
};

bool built_with_sumo();
bool built_with_mujoco();
bool torch_built_with_cuda();  // libtorch's CUDA backend is linked in (a GPU may still be absent)

// Throws MissingPart when the build lacks the part: `what` names what needs it
// ("collect", "eval of a driving agent").
void require_sumo(const std::string& what);
void require_mujoco(const std::string& what);

// "SUMO: yes, MuJoCo: yes"
std::string build_parts_description();

}  // namespace cd
