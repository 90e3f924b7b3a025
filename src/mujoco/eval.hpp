#pragma once
// `causaldrive eval --env NAME`: closed-loop episodes of an agent in a MuJoCo-Image env (SPEC
// section 8), in worker processes (the driving eval's pool and retries), one JSON record per
// finished episode (a rerun resumes; the folder's run.json must match), results.json written
// atomically. Same options, same bytes of results.json (no timings in it).
//
// Agents:
//   a family method (bc-so, bc-oh, residual, fca, keyframe, hd) with --checkpoint RUN: the
//     policy on rendered frames at the checkpoint's size, K frames `stride` steps apart (from
//     the checkpoint). Until the history holds K real frames ((K-1)*stride steps) the env is
//     stepped with the zero action (the driving runner's prefill: never a repeated frame);
//     those steps count in the return and the length, and the policy acts from then on, its
//     action clamped to ctrlrange. residual's memory-only controller is given a_{t-1}, the
//     action executed one step before (zero after the prefill).
//   expert: the planner of `collect --env` (mujoco/expert.hpp) on the true state, from step 0.
//   random: uniform actions in ctrlrange, from step 0.
// Episode i starts from episode_seed(derive_seed(seed, kEvalStream), i): never the initial
// states of a collect run with the same seed.
//
// Copycat measure (results.json "copycat"): R^2 of the least-squares linear prediction of a_t
// from a_{t-1} (a_t ~ W a_{t-1} + b, W: A x A, fit over all pairs of consecutive actions within
// episodes, pooled), R^2 = 1 - sum |a_t - pred|^2 / sum |a_t - mean a|^2 over every component.
// `policy_r2` over the actions the agent chose in these episodes (prefill excluded),
// `expert_data_r2` over the expert's recorded labels in the checkpoint's training data. A
// policy whose R^2 is well above its expert's repeats its previous action more than the expert
// does (copycat). null when undefined (fewer than A + 2 pairs, or constant actions).
#include <cstdint>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "mujoco/expert.hpp"

namespace cd::mj {

inline constexpr uint64_t kEvalStream = 0xe7a1;

struct EvalOptions {
  std::string env;
  std::string agent;       // expert | random | a family method
  std::string label;       // row name in report's tables ("": the agent)
  std::string checkpoint;  // the family method's run folder
  std::string out;
  int episodes = 1;
  uint64_t seed = 0;
  int workers = 1;
  int max_steps = 0;       // > 0: episodes end (truncated) after this many steps
  int max_attempts = 2;    // a crashed worker's episode is run this often
  PlannerOptions planner;  // --agent expert
  std::string expert_policies;  // non-empty: --agent expert is <env>.pt there (make_expert)
  bool quiet = false;
  std::string device = "cpu";  // where a family policy's networks run (eval.device)
  std::string batch = "auto";  // eval.batch: the inference process (batched_inference.hpp)
  // Also write episodes/episode_NNNNNN.h5 (SPEC section 8's layout): the episode as the agent
  // drove it, for the replays of `report --html`.
  bool record = false;
};

struct EvalReport {
  nlohmann::json results;  // what results.json holds
  int run_now = 0;
  long steps = 0;
  double seconds = 0;
};

// Throws ConfigError (unknown env or agent, a checkpoint of another domain, env or action
// size) or DataError (a missing or damaged checkpoint) before any episode runs.
EvalReport evaluate(const EvalOptions& options);

// The copycat R^2 above for episodes of actions (each T x A, row major); NaN when undefined.
double lag1_r2(const std::vector<std::vector<float>>& episodes, int action_dim);

// The one-line table printed after a run (Markdown).
std::string eval_table(const nlohmann::json& results);

}  // namespace cd::mj
