#include "mujoco/mujoco_settings.hpp"

#include "core/error.hpp"

namespace cd {

int PerEnvCount::of(const std::string& env) const {
  if (env == "halfcheetah") return halfcheetah;
  if (env == "hopper") return hopper;
  if (env == "ant") return ant;
  if (env == "reacher") return reacher;
  if (env == "humanoid") return humanoid;
  throw ConfigError("unknown MuJoCo environment '" + env +
                    "' (known: halfcheetah, hopper, ant, reacher, humanoid)");
}

}  // namespace cd
