#pragma once
// MuJoCo-Image data: expert episodes rendered to frames, one HDF5 file each (SPEC section 8),
// in parallel worker processes, resumable (a rerun keeps the files already written).
#include <cstdint>
#include <string>
#include <vector>

#include "data/mujoco_episode.hpp"
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
