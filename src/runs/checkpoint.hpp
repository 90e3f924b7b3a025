#pragma once
// The checkpoint folder written by `causaldrive train`:
//
//   model.pt         network after the last finished epoch (torch::save archive)
//   best.pt          network of the epoch with the lowest validation loss (what agents load)
//   optimizer.pt     Adam state after the last finished epoch (for resuming)
//   checkpoint.json  the commit record: method, settings, input format, data folder, sample
//                    counts, epochs done, best epoch, learning rate, per-epoch metrics
//   metrics.jsonl    one JSON line per finished epoch, regenerated from checkpoint.json
//
// Commit protocol (an interrupted run never leaves a mixed state): after epoch N the new
// .pt files are written atomically under pending names "<name>.e<N>.pending", then
// checkpoint.json (saying N epochs) is written atomically — the commit — and then the pending
// files are renamed to their final names. A later run first rolls pending files of the
// committed epoch forward and deletes any others (an epoch that was never committed).
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "app/settings.hpp"
#include "runs/record.hpp"

namespace cd {

inline constexpr const char* kCheckpointJson = "checkpoint.json";
inline constexpr const char* kMetricsJsonl = "metrics.jsonl";
inline constexpr const char* kModelFile = "model.pt";
inline constexpr const char* kBestFile = "best.pt";
inline constexpr const char* kOptimizerFile = "optimizer.pt";
inline constexpr int kCheckpointVersion = 1;

// What the network reads, fixed by the data it was trained on.
struct InputFormat {
  int channels = 0, height = 0, width = 0;
  int history = 1, stride = 1;
  int action_dim = 2;  // components of the recorded action
  double dt = 0.1, metres_per_pixel = 0.5;
  std::vector<std::string> channel_names;
  // driving (BEV bit planes, actions in [0,1]) | mujoco (RGB bytes / 255, actions in [-1,1],
  // the env's name); written to checkpoint.json only for mujoco, so driving records keep their
  // bytes.
  std::string domain = "driving";
  std::string env;
  // The squash of the action output (PolicyNetsLayout::action_output). Written for data whose
  // actions are not driving's (throttle, brake) pair; a record of such data without it comes from
  // a build that squashed every action with a sigmoid (no negative steer or MuJoCo action) and
  // is refused.
  std::string action_output;
};

struct Checkpoint {
  std::string method;
  nlohmann::json settings;  // settings_to_json of the settings trained with
  ModelSettings model;      // settings["model"], parsed
  InputFormat input;
  std::string data_dir;     // absolute
  long train_samples = 0, val_samples = 0;
  int train_episodes = 0, val_episodes = 0;
  // The validation episodes' file names (diagnose --split val compares exactly these); empty in
  // runs made before they were recorded.
  std::vector<std::string> val_files;
  std::string device;       // cpu | cuda, where it trained
  // How it trained (device/device.hpp ComputeDevice::record: device, precision, deterministic,
  // threads, libtorch, CUDA) of the last session; null in runs made before it was recorded.
  nlohmann::json runtime;
  int epochs_done = 0;
  int best_epoch = 0;       // 0: none yet
  double best_loss = 0;     // validation loss of best_epoch (training loss without validation)
  double lr = 0;            // learning rate of the next epoch
  int bad_epochs = 0;       // epochs since the last improvement (plateau schedule)
  std::vector<EpochMetrics> metrics;
  // What a method keeps beside the common record (keyframe: its action-prediction model's
  // figures; dagger: iterations and expert labels); null when nothing.
  nlohmann::json method_record;
  // Settings that define the networks (settings[...] parsed): seed 001's layout options.
  ResidualSettings residual;
  FcaSettings fca;
};

nlohmann::json checkpoint_to_json(const Checkpoint& c);
// Throws DataError naming `where` when a key is missing or has the wrong type.
Checkpoint checkpoint_from_json(const nlohmann::json& j, const std::string& where);

// Reads dir/checkpoint.json: nullopt when there is none, DataError when it is damaged.
std::optional<Checkpoint> read_checkpoint(const std::string& dir);
// Like read_checkpoint, but a missing checkpoint is a DataError too.
Checkpoint require_checkpoint(const std::string& dir);

// The metrics.jsonl text of a checkpoint: one line per finished epoch.
std::string metrics_jsonl(const Checkpoint& c);

// Name of the pending file of `final_name` for epoch `epoch` (see the commit protocol).
std::string pending_name(const std::string& final_name, int epoch);
// Rolls the pending files of epoch `committed` forward and removes the others, plus
// leftover temporary files. Returns how many were rolled forward.
int settle_pending_files(const std::string& dir, int committed);

}  // namespace cd
