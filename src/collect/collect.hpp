#pragma once
// Expert data collection: episodes in parallel worker processes (libsumo runs one simulation
// per process), one HDF5 file each, resumable.
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "app/settings.hpp"
#include "collect/expert_episode.hpp"

namespace cd {

struct CollectOptions {
  std::string png_dir;  // non-empty: also write every frame as PNG, one folder per episode
  bool quiet = false;   // no progress output
  // Set: each episode is driven by the driver it makes (made in the episode's worker), with
  // the expert's labels recorded (dagger's rollouts).
  std::function<std::unique_ptr<Driver>()> driver;
  // The run folder of the policy the driver runs, if any (dagger's rollouts): its network is
  // served to the workers by batched inference as eval.batch says (batched_inference.hpp).
  std::string policy_checkpoint;
};

struct CollectReport {
  std::vector<EpisodeSummary> episodes;  // all episodes in the folder, by index
  int recorded_now = 0;                  // episodes this run recorded (the rest were kept)
  double seconds = 0;
  long frames = 0;
};

// File name of episode `index` inside the output folder.
std::string episode_file_name(int index);

// The settings a finished data folder records (its collect.json's "settings"), as written;
// nullopt when the folder has no collect.json. Throws DataError naming the file when it is
// damaged.
std::optional<nlohmann::json> recorded_collect_settings(const std::string& folder);

// Records settings.collect.episodes episodes into settings.collect.out. Episodes whose file
// is already complete are kept and skipped. Throws Error when a worker fails twice.
CollectReport collect(const Settings& settings, const CollectOptions& options = {});

}  // namespace cd
