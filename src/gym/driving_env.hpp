#pragma once
// The driving world as a step-by-step environment (SPEC section 9; the Python module's
// causaldrive.make): reset to a task, step with a control, read the frame, the ground truth,
// the expert's action at the current state and, when the episode has ended, its record as
// `eval` writes it.
//
// Tasks come from a suite (a built-in name or a suite file: its episodes in eval's order,
// trial after trial of each task, with the trials' traffic seeds) or from a town (a built-in
// town or a .net.xml: each reset draws the task that `collect` draws for an episode seed, so
// reset(seed = the seed attribute of a collected file) replays that file's task).
//
// Reward (secondary: this is an imitation benchmark): the metres of route progress of the step,
// minus kCollisionPenalty on the step that collides.
#include <cstdint>
#include <memory>
#include <optional>
#include <string>

#include "app/settings.hpp"
#include "bench/metrics.hpp"
#include "bench/runner.hpp"
#include "bench/suite.hpp"
#include "expert/autopilot.hpp"
#include "world/world.hpp"

namespace cd {

inline constexpr double kCollisionPenalty = 100.0;

struct EnvStep {
  double reward = 0;
  bool terminated = false;  // success or collision
  bool truncated = false;   // the task's timeout
  StepResult result;
};

class DrivingEnv {
 public:
  // Throws ConfigError when `name` is neither a suite nor a town, SimError when SUMO fails.
  DrivingEnv(const std::string& name, const Settings& settings);
  ~DrivingEnv();

  const Settings& settings() const { return settings_; }
  bool has_suite() const { return suite_.has_value(); }
  const Suite& suite() const { return *suite_; }
  int trials() const { return trials_; }
  // Episodes of a suite (tasks x trials); 0 for a town (every seed is a task).
  int episodes() const;

  // Starts an episode. A suite: episode `episode` when >= 0, else episode seed % episodes()
  // with a seed, else the next one (after the last, the first again). A town: the task of
  // episode seed `seed`, or with none collect's episode n of collect.seed at the n-th reset.
  void reset(std::optional<uint64_t> seed = std::nullopt, int episode = -1);
  // Applies the control for one step. Error when no episode runs (before reset, after its end).
  EnvStep step(const Control& c);

  bool running() const { return running_; }
  bool started() const { return started_; }
  // The privileged expert's control at the current state (what collect records as the label).
  Control expert_action() const;
  // The record of the finished episode (outcome: success, collision, off-road or a timeout class; events), as in results.json.
  const EpisodeResult& result() const { return result_; }

  int episode() const { return episode_; }        // suite: the episode index; town: -1
  uint64_t episode_seed() const { return seed_; }  // town: the task's seed
  const Task& task() const { return world_->task(); }
  const World& world() const { return *world_; }
  // The world itself, for a loop that drives it another way (a C++ agent through the
  // benchmark runner); reset() before stepping this environment again.
  World& mutable_world() { running_ = false; return *world_; }
  double progress() const { return world_->ego().progress; }

 private:
  Settings settings_;
  std::optional<Suite> suite_;
  int trials_ = 0;
  std::unique_ptr<World> world_;
  Autopilot expert_;
  std::unique_ptr<EpisodeScorer> scorer_;
  EpisodeResult result_;
  int episode_ = -1, next_episode_ = 0, resets_ = 0;
  uint64_t seed_ = 0;
  bool running_ = false, started_ = false;
};

}  // namespace cd
