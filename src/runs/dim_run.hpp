#pragma once
// The run folder of `causaldrive train --method dim|rip` and what reads it.
//
//   dim.json       the commit record: method, settings, input format, data folder, sample
//                  counts, and per member: finished?, its bootstrap sample count, best epoch,
//                  per-epoch metrics
//   member_<k>.pt  weights of member k at its best validation epoch (torch::save archive)
//   metrics.jsonl  one JSON line per finished epoch of a finished member (from dim.json)
//
// Members train one after the other; each is written whole (member_<k>.pt, then dim.json
// marking it finished, both atomically). A member interrupted mid-training is retrained from
// scratch on a rerun, and gives the same bytes: its weights, shuffling and bootstrap come from
// (train.seed, k) only.
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "app/settings.hpp"
#include "runs/checkpoint.hpp"

namespace cd {

inline constexpr const char* kDimJson = "dim.json";
inline constexpr int kDimRunVersion = 1;
std::string dim_member_file(int member);  // "member_<k>.pt"

// An epoch of a member; its losses are mean negative log-likelihoods per sample (nats), kept as
// train_nll and val_nll in the record.
struct DimEpochMetrics : EpochMetrics {
  int member = 0;
};

struct DimMember {
  int index = 0;
  bool finished = false;
  long train_samples = 0;   // after the bootstrap resample
  std::vector<int> episodes;  // rip: the bootstrap draw (episode indices); dim: empty (all)
  int best_epoch = 0;
  double best_nll = 0;      // validation NLL of best_epoch (training NLL without validation)
  std::vector<DimEpochMetrics> metrics;
};

struct DimRun {
  std::string method;       // dim | rip
  nlohmann::json settings;  // settings_to_json of the effective settings
  DimSettings dim;          // settings["dim"], parsed
  InputFormat input;        // history 1, stride 1
  std::string data_dir;     // absolute
  long train_samples = 0, val_samples = 0;
  int train_episodes = 0, val_episodes = 0;
  std::string device;
  nlohmann::json runtime;  // device/device.hpp ComputeDevice::record; null in older runs
  std::vector<DimMember> members;  // dim.ensemble of them

  int finished_members() const;
};

nlohmann::json dim_run_to_json(const DimRun& r);
DimRun dim_run_from_json(const nlohmann::json& j, const std::string& where);  // DataError
// dir/dim.json: nullopt when missing, DataError when damaged.
std::optional<DimRun> read_dim_run(const std::string& dir);
std::string dim_metrics_jsonl(const DimRun& r);

}  // namespace cd
