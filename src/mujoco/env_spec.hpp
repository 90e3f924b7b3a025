#pragma once
// The MuJoCo-Image environments, each declared in one place (EnvPool's way): its MJCF file,
// frame skip, episode limit, Gym's reward, termination and reset noise, and its camera.
// Facts: DESIGN.md "MuJoCo facts" (Gym v3/v4 definitions).
#include <span>
#include <string>
#include <vector>

// MuJoCo's model and data, declared as mujoco.h does: only the files that call MuJoCo include it
// (a build without MuJoCo compiles everything else).
struct mjModel_;
typedef struct mjModel_ mjModel;
struct mjData_;
typedef struct mjData_ mjData;

#include "core/rng.hpp"

namespace cd::mj {

// A camera that follows a body (or, with track_body < 0, looks at a fixed point).
struct CameraSpec {
  int track_body = 1;        // body whose subtree centre of mass the camera follows; -1: fixed
  double distance = 4.0;     // metres from the look-at point
  double azimuth = 90.0;     // degrees; 90 looks along +y, i.e. a side view of motion along x
  double elevation = -20.0;  // degrees, negative looks down
  bool fixed_height = false;  // look at z = lookat[2] instead of the body's height
  double lookat[3] = {0, 0, 0};  // fixed look-at point (x, y used when track_body < 0)
};

struct EnvSpec {
  std::string name;
  std::string model_file;  // inside the assets folder
  int frame_skip = 1;      // physics steps per env step
  int max_steps = 1000;    // Gym's TimeLimit: truncated after this many steps
  // What the reward compares before and after the step (x of the root, torso or centre of mass;
  // for reacher the distance term of the state before the step).
  double (*progress)(const mjModel&, const mjData&) = nullptr;
  // The reward of one step, from the state after it, `before` = progress before it.
  double (*reward)(const mjModel&, const mjData&, double before, std::span<const double> action,
                   double dt) = nullptr;
  // Gym's is_healthy; nullptr: the episode never terminates (only truncates).
  bool (*healthy)(const mjModel&, const mjData&) = nullptr;
  // Gym's reset: perturbs qpos0/qvel = 0 (already in d) with draws from rng.
  void (*reset_noise)(const mjModel&, mjData&, Rng&) = nullptr;
  bool contact_forces = false;  // the reward reads cfrc_ext (computed after each step)
  // Leading qpos entries a state policy does not see (Gym's exclude_current_positions_from_
  // observation: the root's x, or x and y): where the body is must not decide how it moves.
  int position_dims = 0;
  CameraSpec camera;
};

// The spec of `name`; an unknown name is a ConfigError listing the known ones.
const EnvSpec& env_spec(const std::string& name);

// halfcheetah, hopper, ant, reacher, humanoid.
std::vector<std::string> env_names();

}  // namespace cd::mj
