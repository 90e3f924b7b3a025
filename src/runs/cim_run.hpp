#pragma once
// The run folder of the cim family (methods/cim.cpp writes it; its agent and --init / --vae
// read it).
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "app/settings.hpp"

namespace cd {

// The cim run folder (see methods/cim.cpp for the stages that write it):
inline constexpr const char* kCimRunJson = "run.json";         // commit record
inline constexpr const char* kCimVaeFile = "vae.pt";
inline constexpr const char* kCimVaeMetrics = "vae_metrics.jsonl";
inline constexpr const char* kCimSeriesCsv = "series.csv";     // what `causaldrive granger` reads
inline constexpr const char* kCimCausesJson = "causes.json";
inline constexpr const char* kCimPredictorFile = "predictor.pt";
inline constexpr const char* kCimPredictorMetrics = "predictor_metrics.jsonl";
inline constexpr const char* kCimTraversalPng = "traversal.png";
inline constexpr const char* kCimGrangerPng = "granger.png";
inline constexpr int kCimRunVersion = 1;

// A cim run folder's commit record (run.json), as far as loaders need it.
struct CimRunInfo {
  std::string dir, method, data_dir, init, vae_from;
  nlohmann::json record;  // the whole run.json
  VaeSettings vae;        // the settings it was trained with (effective: cim-entangled beta 1)
  CimSettings cim;
  int channels = 0, height = 0, width = 0;
  std::vector<std::string> channel_names;
  std::vector<std::string> stages;  // finished stages: vae, series, causes, predictor, pictures
  bool has_stage(const std::string& stage) const;
};

// dir/run.json: nullopt when there is none, DataError when it is damaged.
std::optional<CimRunInfo> read_cim_run(const std::string& dir);
// Like read_cim_run, but ConfigError (one line naming `role`, e.g. "--init") when the folder
// or its run.json is missing, it holds another method (`method` empty: any of the cim family)
// or a stage of `stages` is not finished.
CimRunInfo require_cim_run(const std::string& dir, const std::string& method,
                           const std::vector<std::string>& stages, const std::string& role);

}  // namespace cd
