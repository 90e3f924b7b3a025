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
//
// Torch stays inside the .cpp files.
#include <cmath>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "app/settings.hpp"
#include "core/geometry.hpp"
#include "learn/checkpoint.hpp"
#include "learn/episode_set.hpp"

namespace cd {

inline constexpr const char* kDimJson = "dim.json";
inline constexpr int kDimRunVersion = 1;
std::string dim_member_file(int member);  // "member_<k>.pt"

struct DimEpochMetrics {
  int member = 0, epoch = 0;  // epoch is 1-based
  double train_nll = 0;       // mean negative log-likelihood per sample (nats)
  std::optional<double> val_nll;
  double lr = 0, seconds = 0, samples_per_s = 0;
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
  std::vector<DimMember> members;  // dim.ensemble of them

  int finished_members() const;
};

nlohmann::json dim_run_to_json(const DimRun& r);
DimRun dim_run_from_json(const nlohmann::json& j, const std::string& where);  // DataError
// dir/dim.json: nullopt when missing, DataError when damaged.
std::optional<DimRun> read_dim_run(const std::string& dir);
std::string dim_metrics_jsonl(const DimRun& r);

// Throws ConfigError when `dir` holds the run of another method (a dim.json of another
// method, or a checkpoint.json or other run record naming one) — used by the trainer and the
// agent so a wrong folder is one clear line.
void refuse_other_method_folder(const std::string& dir, const std::string& method);

// The ego-frame coordinates (x forward, y left) of network-frame point (x, y) seen from pose
// (x0, y0, heading h0; 0 = east, counter-clockwise).
inline void to_ego_frame(double x0, double y0, double h0, double x, double y, double& ex,
                         double& ey);

// A training sample's positions from an episode's poses: past[2k], past[2k+1] = position at
// t - (k+1)*waypoint_step (clamped at the episode's first step), future likewise at
// t + (k+1)*waypoint_step, both in the ego frame of step t. Requires t + horizon*step < T.
void dim_sample_positions(const PackedEpisode& e, int t, const DimSettings& d, float* past,
                          float* future);

struct DimStep {
  std::vector<double> plan;     // H x 2 waypoints (m, ego frame)
  double objective_before = 0;  // J of the initial guess (member 0's mean rollout)
  double objective_after = 0;
  double target_speed = 0;      // m/s implied by the plan
};

// A finished run loaded for closed loop (CPU, eval mode).
class DimPlanner {
 public:
  // Throws ConfigError for a folder of another method (expected_method non-empty), DataError
  // for a missing, damaged or unfinished run.
  explicit DimPlanner(const std::string& dir, const std::string& expected_method = "");
  ~DimPlanner();
  DimPlanner(const DimPlanner&) = delete;
  DimPlanner& operator=(const DimPlanner&) = delete;

  const DimRun& run() const;
  // The planner's own settings (plan_iterations, plan_lr, goal_weight, aggregation) from
  // `planning` instead of the run's: they are used at inference only, never in training.
  void set_planning(const DimSettings& planning);
  // frame: C*H*W bytes 0/255 of the run's input format; past: dim.past x 2 (m, ego frame,
  // most recent first); goal in the ego frame (m).
  DimStep plan(const uint8_t* frame, const std::vector<double>& past, double goal_x,
               double goal_y);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

inline void to_ego_frame(double x0, double y0, double h0, double x, double y, double& ex,
                         double& ey) {
  const Vec2 e = to_ego_frame(Pose2{{x0, y0}, h0}, Vec2{x, y});
  ex = e.x;
  ey = e.y;
}

}  // namespace cd
