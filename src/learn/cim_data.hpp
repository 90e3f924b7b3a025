#pragma once
// Torch-free parts of the cim pipeline: the grey view the VAE sees, Granger cause selection
// over latent series, the ground-truth check of the selected latents, and the run folder's
// names. (Networks: nn/beta_vae.hpp, nn/speed_predictor.hpp; stages: learn/cim.cpp.)
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "app/settings.hpp"
#include "causal/granger.hpp"
#include "learn/episode_set.hpp"

namespace cd {

// The cim run folder (see learn/cim.cpp for the stages that write it):
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

// The VAE's input: the BEV channels named by vae.view ("a+b": OR-ed into one plane), resized
// to 64x64 by area averaging when the BEV has another size (pixel values in [0, 1]).
struct CimView {
  std::vector<int> channels;  // indices into the BEV channels
  uint8_t mask = 0;           // bit c set for each channel c (packed frames)
  int channel_count = 0, height = 0, width = 0;  // the BEV frame
  // Source rectangle of each output row / column: [y0[i], y1[i]) and [x0[j], x1[j]).
  std::vector<int> y0, y1, x0, x1;
};

// Throws ConfigError naming the unknown channel and the known ones.
CimView resolve_view(const std::string& view, const std::vector<std::string>& channel_names,
                     int height, int width);
// One 64x64 plane from a packed frame (H*W bytes, bit c = channel c) ...
void view_from_packed(const CimView& v, const uint8_t* packed, float* out);
// ... or from C planes of H*W bytes, 0/255 (what agents are given).
void view_from_planes(const CimView& v, const uint8_t* planes, float* out);

// Granger test of every latent against the speed.
struct LatentTest {
  int index = 0;
  GrangerTest test;
  double p_adjusted = 1;
  bool significant = false;  // p_adjusted <= alpha
  bool selected = false;     // an input of the speed predictor
};

struct CauseSelection {
  std::vector<LatentTest> tests;  // one per latent, by index
  // Significant latents by (p_adjusted, larger F, index), capped at cim.max_causes, as
  // indices in ascending order; the smallest-p latent alone when none is significant.
  std::vector<int> ranked;
  std::vector<int> selected;  // the predictor's inputs: `ranked`, or every latent (cim-mlp)
  int significant = 0;
  bool fallback = false;      // nothing was significant: `ranked` holds the best latent
  bool capped = false;        // more were significant than cim.max_causes
  long rows = 0;              // regression rows of the tests
  double threshold_p = 0;     // raw p-value at or below which a test is significant
};

// speed: one series per episode; latents[i]: latent i's series per episode (same lengths).
// use_all: cim-mlp (every latent is an input; the tests are still run and recorded).
CauseSelection select_causes(const std::vector<std::vector<double>>& speed,
                             const std::vector<std::vector<std::vector<double>>>& latents,
                             const CimSettings& cim, bool use_all);

// The ground-truth causes the selected latents are compared with (names, in this order):
// lead_distance (min(d, 60), 60 without a leader), lead_present, red_light (tl_state red or
// yellow and tl_distance < 30), path_free, ped_on_path. NaN when the episode lacks the series.
const std::vector<std::string>& ground_truth_names();
double ground_truth_value(const PackedEpisode& ep, const std::string& name, int t);

// Pearson correlation; NaN when either series is constant or they are shorter than 2.
double pearson(const std::vector<double>& a, const std::vector<double>& b);

// JSON number, or null for NaN / infinity.
nlohmann::json json_number(double v);

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
