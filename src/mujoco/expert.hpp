#pragma once
// Experts for the MuJoCo-Image environments: state -> action, queryable at any state (DAgger).
//
// The expert here is a sampling-based planner (MPPI) on the true simulator: at each query it
// rolls out `samples` perturbed action sequences of `horizon` steps from the given state in a
// private copy of the env (set_state), and returns the first action of their reward-weighted
// mean. No training, no torch; its cost is samples x horizon x iterations env steps per query.
// Its previous plan, shifted by one step, seeds the next query (warm start), so a run of queries
// along an episode is cheaper to make good than isolated ones; every draw comes from its seed.
// A rollout that ends healthy earns a terminal value (its last reward continued), one that
// terminates (falls) a penalty larger than any return; the noise is time-correlated.
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "core/rng.hpp"
#include "mujoco/env.hpp"
#include "mujoco/mujoco_settings.hpp"

namespace cd::mj {

class Expert {
 public:
  virtual ~Expert() = default;
  // The action for `state` (qpos then qvel), within the env's ctrlrange.
  virtual std::vector<double> act(std::span<const double> state) = 0;
  virtual std::string describe() const = 0;  // one line: kind and settings (recorded in data)
};


struct PlannerOptions {
  int samples = 0;           // rollouts per iteration; 0: the env's default
  int horizon = 0;           // env steps per rollout; 0: the env's default
  int iterations = 0;        // refinements per query; 0: the env's default
  double sigma = 0;          // exploration noise, fraction of the half ctrlrange; 0: default
  double temperature = 0;    // weights exp((R - max R) / (temperature (max R - min R))); 0: default
  // Time correlation of the noise along a rollout (0: white; 0.9: smooth); < 0: the env's default.
  double smoothing = -1;
  // Terminal value: the rollout's last reward counted this many more times (what continuing at
  // the final speed, upright, is worth beyond the horizon); < 0: the env's default.
  double terminal_steps = -1;
  uint64_t seed = 0;
};

// The options with the env's defaults filled in where a field is 0.
PlannerOptions planner_defaults(const std::string& env, PlannerOptions options = {});
// The options the [mujoco] planner_* settings give (0 / < 0: the env's default).
PlannerOptions planner_options(const MujocoSettings& m);

// The folder of expert policies the [mujoco] expert_policies setting names for `env`: "" (the
// default) is the experts shipped with causaldrive (experts/ in the source tree) when one
// exists for the env and `planner` is untuned (every planner_* setting and flag at its
// default: asking for a planner setting asks for the planner), else the planner; "planner" is
// always the planner (returned as ""); any other value is that folder.
std::string expert_policies_for(const std::string& setting, const std::string& env,
                                const PlannerOptions& planner);

// The expert of `env`: the trained policy `policies`/<env>.pt (mj::PolicyExpert,
// mujoco/sac.hpp) when `policies` is not empty, else the planner with `planner`'s settings.
std::unique_ptr<Expert> make_expert(const std::string& env, const PlannerOptions& planner,
                                    const std::string& policies);

class PlannerExpert : public Expert {
 public:
  PlannerExpert(const std::string& env, const PlannerOptions& options);
  std::vector<double> act(std::span<const double> state) override;
  std::string describe() const override;
  // Forgets the warm start (a new episode).
  void reset();
  // Env steps simulated so far (the planner's cost).
  long simulated_steps() const { return simulated_steps_; }

 private:
  double rollout(std::span<const double> state, const std::vector<double>& plan);
  void sample_noise(std::vector<double>& plan, double sigma);

  Env sim_;
  PlannerOptions options_;
  std::vector<double> low_, high_;
  int dim_;
  std::vector<double> mean_;  // horizon x dim, the current plan
  Rng rng_;
  long simulated_steps_ = 0;
};

}  // namespace cd::mj
