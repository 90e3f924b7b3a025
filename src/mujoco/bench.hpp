#pragma once
// The MuJoCo-Image benchmarks of `causaldrive bench` (env, expert), printed as text or one
// JSON line.
#include <cstdint>
#include <string>
#include <vector>

#include "mujoco/expert.hpp"

namespace cd::mj {

// `bench env`'s options (its command line).
struct EnvBenchArgs {
  std::string env;
  std::vector<int> sizes{64};
  long steps = 2000;
  int slices = 6;
  int expert_steps = 0;
  uint64_t seed = 0;
  bool json = false;
};

// Bare physics steps/s against physics + rendering per frame size, interleaved in one run.
void bench_env(const EnvBenchArgs& a);

// The planner expert in closed loop from a seeded reset: its return and cost per step.
void bench_expert(const std::string& env_name, const PlannerOptions& options, int steps,
                  uint64_t seed, bool json);

}  // namespace cd::mj
