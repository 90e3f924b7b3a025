#pragma once
// A state-based expert trained by soft actor-critic (Haarnoja et al. 2018, with the learned
// temperature of the 2019 version) on the true simulator, and the expert that acts with it.
//
// Why SAC besides the planner (mujoco/expert.hpp): the planner's action is its best random
// draw, so its labels are a noisy function of the state that image policies cannot learn (the
// held-out state -> label R^2 of halfcheetah's planner data is below 0). SAC's deterministic
// action, tanh of the actor's mean, is a smooth function of the state: an expert to imitate.
//
//   SacOptions o;  o.steps = 300000;
//   SacReport r = train_sac("halfcheetah", o, "experts/halfcheetah.pt");
//   PolicyExpert expert("experts/halfcheetah.pt", "halfcheetah");
//   std::vector<double> a = expert.act(env.state());
//
// The policy sees the state without its leading position_dims qpos entries (EnvSpec). One file
// holds the actor's weights and its sizes. Same seed and thread count, same bytes.
#include <cstdint>
#include <functional>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "mujoco/expert.hpp"

namespace cd::mj {

struct SacOptions {
  long steps = 300000;        // env steps (one gradient update per step after start_steps)
  long start_steps = 10000;   // uniform random actions first
  int batch = 256;
  int hidden = 256;           // two hidden layers of this width, actor and both critics
  double lr = 3e-4;           // Adam, all three optimizers
  double gamma = 0.99;
  double tau = 0.005;         // target critics' Polyak rate
  long eval_every = 10000;    // env steps between evaluations of the deterministic policy
  int eval_episodes = 5;      // seeded episodes per evaluation (their own seeds)
  uint64_t seed = 0;
  int threads = 1;            // torch threads; small networks run fastest on one
  // auto | cpu | cuda: where the networks and their updates run (the replay buffer stays in
  // host memory). One small update per env step: the CPU is the default.
  std::string device = "cpu";
};

struct SacEvaluation {
  long steps = 0;        // env steps trained when evaluated
  double mean_return = 0, sd_return = 0;
  double seconds = 0;    // training time so far
};

struct SacReport {
  std::vector<SacEvaluation> evaluations;
  SacEvaluation best;    // the saved policy is the one of the best evaluation
  double seconds = 0;    // wall time of the whole training
  long episodes = 0;     // training episodes started
};

// Trains on `env` and writes the best evaluated policy to `out` (atomically, when an evaluation
// improves on the best so far) and a JSON record beside it (`out` with .json). `log` gets one
// line per evaluation (nullptr: silent). Throws ConfigError for an unknown env or bad options.
//
// Resumable: every evaluation also writes sac_resume_path(out) (networks, optimisers, the
// replay buffer, the random streams, the env's exact state); a call that finds it continues
// from there with the same bytes as a run never stopped (the options must be the same; steps
// may grow), and the file is removed when the run finishes. A call whose `out` holds a finished
// run with the same options returns its record and trains nothing; an `out` that exists
// otherwise is a ConfigError (never overwritten). A corrupt resume file is a DataError.
std::string sac_resume_path(const std::string& out);
SacReport train_sac(const std::string& env, const SacOptions& options, const std::string& out,
                    const std::function<void(const std::string&)>& log = nullptr);

// The policy's input for a state (qpos then qvel) of `env`.
std::vector<float> policy_input(const EnvSpec& spec, int nq, std::span<const double> state);

// The deterministic action of a trained policy (tanh of the actor's mean, scaled to the env's
// ctrlrange). Throws DataError for a missing or unreadable file, or one trained for another
// env's sizes.
class PolicyExpert : public Expert {
 public:
  PolicyExpert(const std::string& path, const std::string& env);
  ~PolicyExpert() override;
  std::vector<double> act(std::span<const double> state) override;
  std::string describe() const override;

 private:
  struct Net;
  std::unique_ptr<Net> net_;
  std::string path_;
  const EnvSpec& spec_;
  int nq_ = 0;
  std::vector<double> low_, high_;
};

}  // namespace cd::mj
