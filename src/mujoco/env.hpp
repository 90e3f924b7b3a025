#pragma once
// One MuJoCo-Image environment: a shared model (mujoco/model.hpp), its own mjData, Gym's step
// rules from its EnvSpec, and an offscreen renderer made on the first render.
//
//   Env env("hopper");
//   Frame obs = env.reset(seed);          // seeded initial-state noise, then the first frame
//   StepResult r = env.step(action);      // frame_skip physics steps, reward, termination
//   env.render(obs.data());               // the frame of the new state (C x H x W, RGB)
//
// state() / set_state() give qpos then qvel (nq + nv values), so that an expert can be asked at
// any state and a planner can roll out copies of the env.
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "mujoco/env_spec.hpp"
#include "mujoco/model.hpp"

namespace cd::mj {

class OffscreenRenderer;

struct EnvOptions {
  int width = 64, height = 64;  // rendered frame size
  std::string assets_dir;       // empty: mj::assets_dir()
};

struct StepResult {
  double reward = 0;
  bool terminated = false;  // Gym's unhealthy state
  bool truncated = false;   // the episode limit reached (and not terminated)
};

using Frame = std::vector<uint8_t>;  // channels() x height x width, RGB, top row first

class Env {
 public:
  // Throws ConfigError for an unknown name or a missing model file.
  explicit Env(const std::string& name, const EnvOptions& options = {});
  ~Env();
  Env(const Env&) = delete;
  Env& operator=(const Env&) = delete;

  const EnvSpec& spec() const { return spec_; }
  const std::string& name() const { return spec_.name; }
  double dt() const;  // seconds per step
  int frame_skip() const { return spec_.frame_skip; }
  int max_steps() const { return spec_.max_steps; }

  int action_dim() const;
  std::vector<double> action_low() const;   // actuator ctrlrange
  std::vector<double> action_high() const;
  int state_dim() const;
  int qpos_dim() const;

  // The initial state qpos0 (zero velocity) plus the spec's noise drawn from Rng(seed); returns
  // the first frame. Same seed, same state, same frame bytes.
  Frame reset(uint64_t seed);
  // Applies the action (Gym: as given; the simulator clamps it to ctrlrange, the control cost
  // counts it as given) for frame_skip physics steps. A wrong size or a non-finite value is a
  // SimError. Does not render.
  StepResult step(std::span<const double> action);
  int steps() const { return steps_; }  // env steps since reset

  std::vector<double> state() const;  // qpos then qvel
  // Sets qpos, qvel (and recomputes positions); the step counter is kept.
  void set_state(std::span<const double> state);
  // The exact integration state (time, step counter, qpos, qvel, activations, controls and the
  // solver's warm start): restore() continues bit for bit as the env would have, which
  // set_state (a state alone, warm start cleared) does not. For resuming a training run.
  std::vector<double> snapshot() const;
  void restore(std::span<const double> snapshot);  // a snapshot of this env; else SimError

  int channels() const { return 3; }
  int width() const { return options_.width; }
  int height() const { return options_.height; }
  size_t frame_bytes() const { return static_cast<size_t>(channels()) * width() * height(); }
  void render(uint8_t* out);  // frame_bytes() bytes
  Frame render();

  // The simulator, read-only: for tests and analysis.
  const mjModel& model() const { return *model_; }
  const mjData& data() const { return *data_; }

 private:
  void recompute();  // positions, velocities, contact forces of the current state

  const EnvSpec& spec_;
  EnvOptions options_;
  ModelPtr model_;
  mjData* data_ = nullptr;
  std::unique_ptr<OffscreenRenderer> renderer_;
  int steps_ = 0;
};

}  // namespace cd::mj
