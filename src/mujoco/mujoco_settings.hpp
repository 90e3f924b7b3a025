#pragma once
// The [mujoco] settings: what `collect --env` and `eval --env` do when a config is given
// (configs/mujoco_paper.toml); command-line flags override them. Torch- and MuJoCo-free.
#include <cstdint>
#include <string>

namespace cd {

// One count per MuJoCo-Image environment (SPEC section 8).
struct PerEnvCount {
  int halfcheetah = 10, hopper = 10, ant = 1, reacher = 100, humanoid = 10;
  // The count of `env`; throws ConfigError for an unknown name.
  int of(const std::string& env) const;
};

struct MujocoNoiseSettings {
  bool enabled = false;
  double rate = 0.02;              // chance per step that a noise window starts
  int min_steps = 5, max_steps = 15;
  double sigma = 0.3;              // fraction of the half ctrlrange
};

struct MujocoSettings {
  int size = 64;                   // frame width and height in pixels
  int workers = 2;                 // collect and eval worker processes
  uint64_t seed = 0;               // collect's run seed (eval --env takes its own --seed)
  int max_steps = 0;               // > 0: episodes end after this many steps (truncated)
  // collect --env: expert episodes per env (episode limits: 1000 steps, reacher 50). The
  // defaults are seed 001's sample counts where it gives them (ant 1k, reacher 5k samples);
  // humanoid's 200k is scaled to 10k for the planner's cost (about 0.6 s per step).
  PerEnvCount episodes;
  int eval_episodes = 10;          // eval --env: seeded episodes
  MujocoNoiseSettings noise;       // collect --env's noise injection (labels stay the expert's)
  // The expert planner (mj::PlannerOptions; collect --env's --planner-* flags override them):
  // 0 (smoothing, terminal_steps: < 0) takes the env's default.
  int planner_samples = 0;         // rollouts per iteration
  int planner_horizon = 0;         // env steps per rollout
  int planner_iterations = 0;      // refinements per query
  double planner_sigma = 0;        // exploration noise, fraction of the half ctrlrange
  double planner_temperature = 0;  // weight temperature
  double planner_smoothing = -1;   // time correlation of the noise (0 white, < 1)
  double planner_terminal_steps = -1;  // extra weight of a rollout's last reward
  // A folder of trained state policies (`causaldrive train-expert`, one <env>.pt each): when
  // set, the expert of collect, eval and dagger is the env's policy there, not the planner.
  std::string expert_policies;
};

}  // namespace cd
