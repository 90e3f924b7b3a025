#pragma once
// The imitation diagnosis (SPEC section 10): what an image policy learned, open-loop. A trained
// family policy is run over the frames of a data folder and its action is compared with the
// expert's label, situation by situation, per action component: count, mean and sd of label and
// prediction, MAE and R^2 = 1 - SSE/SST. A near-constant output shows as pred_sd far below
// label_sd and R^2 <= 0; the text table marks it "flat".
//
// Situations (driving): datasets/situation.hpp.
// MuJoCo-Image data has the one situation "all" and the components a0..aK.
#include <cstdint>
#include <string>
#include <vector>

#include <nlohmann/json_fwd.hpp>

#include "datasets/episode_set.hpp"
#include "datasets/situation.hpp"

namespace cd {

// Running sums of one (situation, component) cell.
struct ComponentStats {
  long count = 0;
  double label_mean = 0, label_sd = 0, pred_mean = 0, pred_sd = 0, mae = 0;
  double r2 = 0;         // 1 - SSE/SST
  bool r2_defined = false;  // false when the labels are constant (SST = 0) and SSE > 0
};

struct SituationStats {
  std::string name;
  long count = 0;
  std::vector<ComponentStats> components;  // one per DiagnosisReport::components
};

struct DiagnosisReport {
  std::string checkpoint, data, method, split;  // split: val | all
  std::string domain = kDrivingDomain;
  std::vector<std::string> components;  // throttle, brake[, steer] | target_speed | a0..aK
  long frames = 0;                      // frames compared
  std::vector<std::string> episodes;    // split val: the compared episodes' file names
  std::vector<SituationStats> situations;  // every situation, in situation_names() order
};

// One frame's label and prediction, as the diagnosis sees it.
struct DiagnosedFrame {
  int episode = 0, t = 0;
  std::vector<float> label, prediction;
};

// The statistics of frames (any source: a policy, or a test's hand-made predictions).
// `situations`: one mask per frame (situations_at, or 1 << kAllFrames for MuJoCo).
DiagnosisReport summarize_diagnosis(const std::vector<std::string>& components,
                                    const std::vector<DiagnosedFrame>& frames,
                                    const std::vector<uint32_t>& situations,
                                    const std::string& domain);

struct DiagnoseOptions {
  std::string checkpoint;   // a `causaldrive train` folder of a family method
  std::string data;         // a `causaldrive collect` folder (driving or MuJoCo-Image)
  std::string split = "auto";  // auto (val when data is the folder trained on, else all) | val | all
  long max_frames = 0;      // > 0: at most this many frames, spread evenly
  std::string plots;        // folder for PNGs of prediction and label; "" = none
  std::vector<int> plot_episodes;  // episode indices in the data folder; empty: the first 3 used
  SituationRules rules;
};

// The components, labels and situations of frame t as the checkpoint's head sees them.
// Throws DataError / ConfigError like PolicyRunner and load_episode_set, and ConfigError for a
// split that cannot be honoured (val on another data folder).
DiagnosisReport run_diagnosis(const DiagnoseOptions& options);

nlohmann::json diagnosis_json(const DiagnosisReport& report);
std::string diagnosis_table(const DiagnosisReport& report);

// The PNG of one episode: a strip of situation colours (top) and one panel per component with
// the label (black) and the prediction (red) over time. Colours: situation_colour().
void write_diagnosis_png(const std::string& path, const std::vector<std::string>& components,
                         const std::vector<DiagnosedFrame>& frames,
                         const std::vector<uint32_t>& situations);
// RGB of a situation in the PNG's strip (the first situation of a mask after "all" wins).
void situation_colour(uint32_t mask, uint8_t rgb[3]);

}  // namespace cd
