#pragma once
// A finished dim / rip run (runs/dim_run.hpp) loaded for closed loop: plans a trajectory by
// likelihood ascent toward a goal (CPU, eval mode). Torch stays inside the .cpp.
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "runs/dim_run.hpp"

namespace cd {

struct DimStep {
  std::vector<double> plan;     // H x 2 waypoints (m, ego frame)
  double objective_before = 0;  // J of the initial guess (member 0's mean rollout)
  double objective_after = 0;   // J of the plan (>= objective_before: the best iterate)
  double moved_m = 0;           // how far the ascent moved it: mean waypoint distance, m
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
  // The planner's own settings (plan_iterations, plan_lr, goal_weight, goal, plan_speed,
  // aggregation) from `planning` instead of the run's: used at inference only, never in
  // training.
  void set_planning(const DimSettings& planning);
  // frame: C*H*W bytes 0/255 of the run's input format; past: dim.past x 2 (m, ego frame,
  // most recent first); goal in the ego frame (m).
  DimStep plan(const uint8_t* frame, const std::vector<double>& past, double goal_x,
               double goal_y);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace cd
