#include "inference/dim_planner.hpp"

#include <filesystem>

#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "nn/dim_net.hpp"
#include "runs/record.hpp"
#include "sense/grey_view.hpp"

namespace cd {

namespace fs = std::filesystem;

struct DimPlanner::Impl {
  DimRun run;
  std::unique_ptr<DimEnsemble> ensemble;
  DimPlanOptions options;
  torch::Tensor frame;  // 1 x C x H x W, reused
  std::vector<bool> keep;  // dim.view: the channels the model sees
  bool speed_over_horizon = false;  // dim.plan_speed = "horizon"

  void set_planning(const DimSettings& p) {
    options = {p.plan_iterations, p.plan_lr, p.goal_weight, p.aggregation, p.goal == "segment"};
    speed_over_horizon = p.plan_speed == "horizon";
  }
};

DimPlanner::DimPlanner(const std::string& dir, const std::string& expected_method)
    : impl_(std::make_unique<Impl>()) {
  std::error_code ec;
  if (!fs::is_directory(dir, ec))
    throw DataError("no run folder " + dir + " (train one with `causaldrive train --method " +
                    (expected_method.empty() ? std::string("dim") : expected_method) + "`)");
  if (!expected_method.empty()) refuse_other_method_folder(dir, expected_method);
  std::optional<DimRun> run = read_dim_run(dir);
  if (!run)
    throw DataError(dir + " holds no dim/rip run (no " + kDimJson + ")");
  if (!expected_method.empty() && run->method != expected_method)
    throw ConfigError(dir + " holds a run of method '" + run->method + "', not '" +
                      expected_method + "'");
  if (run->finished_members() != static_cast<int>(run->members.size()))
    throw DataError(dir + ": training is not finished (" +
                    std::to_string(run->finished_members()) + " of " +
                    std::to_string(run->members.size()) +
                    " members): rerun the same `causaldrive train` command");
  impl_->run = *run;
  const DimSettings& d = run->dim;
  const DimNetOptions no =
      dim_net_options(d, run->input.channels, run->input.height, run->input.width);
  std::vector<DimNet> members;
  for (const DimMember& m : run->members) {
    DimNet net(no);
    const std::string path = dir + "/" + dim_member_file(m.index);
    load_module_bytes(*net, read_file_bytes(path), torch::kCPU, path);
    members.push_back(net);
  }
  impl_->ensemble = std::make_unique<DimEnsemble>(std::move(members));
  impl_->set_planning(d);
  impl_->frame = torch::zeros({1, no.channels, no.height, no.width});
  impl_->keep = run->input.channel_names.empty()
                    ? std::vector<bool>(static_cast<size_t>(no.channels), true)
                    : view_channel_flags(d.view, run->input.channel_names, "dim.view");
}

DimPlanner::~DimPlanner() = default;

const DimRun& DimPlanner::run() const { return impl_->run; }

void DimPlanner::set_planning(const DimSettings& p) {
  impl_->set_planning(p);
}

DimStep DimPlanner::plan(const uint8_t* frame, const std::vector<double>& past, double goal_x,
                         double goal_y) {
  const DimSettings& d = impl_->run.dim;
  if (static_cast<int>(past.size()) != 2 * d.past)
    throw Error("dim planner: " + std::to_string(past.size()) + " past values for dim.past = " +
                std::to_string(d.past));
  float* f = impl_->frame.data_ptr<float>();
  const int64_t n = impl_->frame.numel();
  for (int64_t i = 0; i < n; ++i) f[i] = frame[i] ? 1.0f : 0.0f;
  blank_other_channels(impl_->keep, static_cast<size_t>(n) / impl_->keep.size(), f);
  torch::Tensor p = torch::empty({1, d.past, 2});
  for (int i = 0; i < 2 * d.past; ++i) p.data_ptr<float>()[i] = static_cast<float>(past[i]);
  DimCondition c = impl_->ensemble->condition(impl_->frame, p);
  torch::Tensor goal = torch::tensor({static_cast<float>(goal_x), static_cast<float>(goal_y)});
  DimPlan pl = plan_trajectory(*impl_->ensemble, c, goal, impl_->options);
  DimStep step;
  torch::Tensor z = pl.z.to(torch::kFloat64).contiguous();
  step.plan.assign(z.data_ptr<double>(), z.data_ptr<double>() + z.numel());
  step.objective_before = pl.objective_before;
  step.objective_after = pl.objective_after;
  step.moved_m = pl.moved_m;
  step.target_speed =
      implied_speed(pl.z, d.waypoint_step, impl_->run.input.dt, impl_->speed_over_horizon);
  return step;
}

}  // namespace cd
