#pragma once
// MuJoCo-Image data: expert episodes rendered to frames, one HDF5 file each (SPEC section 8),
// in parallel worker processes, resumable (a rerun keeps the files already written).
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "data/mujoco_episode.hpp"
#include "mujoco/env.hpp"
#include "mujoco/expert.hpp"

namespace cd::mj {

// Noise injection: short windows in which the executed action is the expert's plus Gaussian
// noise (the label stays the expert's; the row's `noise` is 1), as in the driving data.
struct NoiseOptions {
  bool enabled = false;
  double rate = 0.02;         // chance per step that a window starts
  int min_steps = 5, max_steps = 15;  // window length, uniform
  double sigma = 0.3;         // noise, fraction of the half ctrlrange
};

// What executes the actions of a recorded episode in place of the expert (dagger's closed-loop
// rollouts). The expert's label is recorded at every visited state whatever is executed.
class Driver {
 public:
  virtual ~Driver() = default;
  virtual void begin_episode(uint64_t episode_seed) = 0;
  // The action executed at this step, given the step's frame and the expert's label for it.
  virtual std::vector<double> drive(const Frame& frame, const std::vector<double>& label) = 0;
  virtual std::string describe() const = 0;  // one line, recorded in the file (`driver`)
};

struct CollectOptions {
  std::string env;
  std::string out;
  int episodes = 1;
  uint64_t seed = 0;
  int workers = 1;
  int width = 64, height = 64;
  int max_steps = 0;  // > 0: episodes end (truncated) after this many steps, below the env limit
  NoiseOptions noise;
  PlannerOptions planner;  // the expert; its seed is derived per episode
  std::string expert_policies;  // non-empty: the expert is <env>.pt there (make_expert)
  // Made once per episode (in its worker) when set; noise injection must then be off.
  std::function<std::unique_ptr<Driver>()> driver;
  // The run folder of the policy the driver runs, if any (dagger's rollouts), and eval.batch:
  // its network is then served to the workers by batched inference (batched_inference.hpp).
  std::string policy_checkpoint;
  std::string batch = "auto";
  std::string device = "cpu";  // where that network runs (eval.device, resolved)
  bool quiet = false;
};

struct CollectReport {
  int episodes = 0;      // files in the folder after the run
  int recorded_now = 0;  // written by this run
  long frames = 0;       // frames written by this run
  double seconds = 0;
  std::vector<double> returns;  // per episode, in index order
};

// Episode `index` of the run, in memory. Same options and index, same bytes.
MujocoEpisode record_episode(const CollectOptions& options, int index);

// Records options.episodes episodes into options.out (episode_000000.h5, ...) and a summary
// collect.json. Throws ConfigError for an unknown env or a missing model before any work.
CollectReport collect(const CollectOptions& options);

}  // namespace cd::mj
