#include "learn/dim_run.hpp"

#include <algorithm>
#include <filesystem>

#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "nn/dim_net.hpp"

namespace cd {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {


DimSettings dim_from_json(const json& j, const std::string& where) {
  JsonFields f{j, where};
  DimSettings d;
  d.horizon = f.get<int>("horizon");
  d.waypoint_step = f.get<int>("waypoint_step");
  d.past = f.get<int>("past");
  d.features = f.get<int>("features");
  d.hidden = f.get<int>("hidden");
  d.min_std = f.get<double>("min_std");
  d.plan_iterations = f.get<int>("plan_iterations");
  d.plan_lr = f.get<double>("plan_lr");
  d.goal_distance = f.get<double>("goal_distance");
  d.goal_weight = f.get<double>("goal_weight");
  d.ensemble = f.get<int>("ensemble");
  d.aggregation = f.get<std::string>("aggregation");
  if (d.horizon < 1 || d.waypoint_step < 1 || d.past < 1 || d.features < 1 || d.hidden < 1 ||
      d.ensemble < 1 || d.min_std <= 0)
    throw DataError(where + ": dim settings out of range");
  return d;
}

json epoch_json(const DimEpochMetrics& m) {
  json j = {{"member", m.member},       {"epoch", m.epoch},
            {"train_nll", m.train_nll}, {"val_nll", nullptr},
            {"lr", m.lr},               {"seconds", m.seconds},
            {"samples_per_s", m.samples_per_s}};
  if (m.val_nll) j["val_nll"] = *m.val_nll;
  return j;
}

}  // namespace

std::string dim_member_file(int member) { return "member_" + std::to_string(member) + ".pt"; }

int DimRun::finished_members() const {
  return static_cast<int>(std::count_if(members.begin(), members.end(),
                                        [](const DimMember& m) { return m.finished; }));
}

json dim_run_to_json(const DimRun& r) {
  json members = json::array();
  for (const DimMember& m : r.members) {
    json metrics = json::array();
    for (const auto& e : m.metrics) metrics.push_back(epoch_json(e));
    members.push_back({{"member", m.index},
                       {"finished", m.finished},
                       {"file", dim_member_file(m.index)},
                       {"train_samples", m.train_samples},
                       {"bootstrap_episodes", m.episodes},
                       {"best_epoch", m.best_epoch},
                       {"best_nll", m.best_nll},
                       {"metrics", metrics}});
  }
  return {{"format", "causaldrive-dim-run"},
          {"version", kDimRunVersion},
          {"method", r.method},
          {"settings", r.settings},
          {"input",
           {{"channels", r.input.channels},
            {"height", r.input.height},
            {"width", r.input.width},
            {"history", 1},
            {"stride", 1},
            {"dt", r.input.dt},
            {"metres_per_pixel", r.input.metres_per_pixel},
            {"channel_names", r.input.channel_names}}},
          {"data", r.data_dir},
          {"samples", {{"train", r.train_samples}, {"val", r.val_samples}}},
          {"episodes", {{"train", r.train_episodes}, {"val", r.val_episodes}}},
          {"device", r.device},
          {"members_done", r.finished_members()},
          {"members", members}};
}

DimRun dim_run_from_json(const json& j, const std::string& where) {
  JsonFields f{j, where};
  if (f.get<std::string>("format") != "causaldrive-dim-run")
    throw DataError(where + ": not a causaldrive dim run record");
  if (int v = f.get<int>("version"); v != kDimRunVersion)
    throw DataError(where + ": dim run version " + std::to_string(v) + " (this build reads " +
                    std::to_string(kDimRunVersion) + ")");
  DimRun r;
  r.method = f.get<std::string>("method");
  r.settings = f.at("settings");
  r.dim = dim_from_json(JsonFields{r.settings, where}.at("dim"), where + " (settings.dim)");
  JsonFields in{f.at("input"), where};
  r.input.channels = in.get<int>("channels");
  r.input.height = in.get<int>("height");
  r.input.width = in.get<int>("width");
  r.input.dt = in.get<double>("dt");
  r.input.metres_per_pixel = in.get<double>("metres_per_pixel");
  r.input.channel_names = in.get<std::vector<std::string>>("channel_names");
  if (r.input.channels < 1 || r.input.height < 1 || r.input.width < 1 || r.input.dt <= 0)
    throw DataError(where + ": input format out of range");
  r.data_dir = f.get<std::string>("data");
  JsonFields samples{f.at("samples"), where}, episodes{f.at("episodes"), where};
  r.train_samples = samples.get<long>("train");
  r.val_samples = samples.get<long>("val");
  r.train_episodes = episodes.get<int>("train");
  r.val_episodes = episodes.get<int>("val");
  r.device = f.get<std::string>("device");
  const json& members = f.at("members");
  if (!members.is_array()) throw DataError(where + ": key 'members' is not an array");
  for (const json& mj : members) {
    JsonFields m{mj, where};
    DimMember d;
    d.index = m.get<int>("member");
    d.finished = m.get<bool>("finished");
    d.train_samples = m.get<long>("train_samples");
    d.episodes = m.get<std::vector<int>>("bootstrap_episodes");
    d.best_epoch = m.get<int>("best_epoch");
    d.best_nll = m.get<double>("best_nll");
    const json& metrics = m.at("metrics");
    if (!metrics.is_array()) throw DataError(where + ": a member's 'metrics' is not an array");
    for (const json& ej : metrics) {
      JsonFields e{ej, where};
      DimEpochMetrics em;
      em.member = e.get<int>("member");
      em.epoch = e.get<int>("epoch");
      em.train_nll = e.get<double>("train_nll");
      if (!e.at("val_nll").is_null()) em.val_nll = e.get<double>("val_nll");
      em.lr = e.get<double>("lr");
      em.seconds = e.get<double>("seconds");
      em.samples_per_s = e.get<double>("samples_per_s");
      d.metrics.push_back(em);
    }
    if (d.index != static_cast<int>(r.members.size()))
      throw DataError(where + ": members out of order");
    r.members.push_back(std::move(d));
  }
  if (static_cast<int>(r.members.size()) != r.dim.ensemble)
    throw DataError(where + ": " + std::to_string(r.members.size()) + " members listed for " +
                    "dim.ensemble = " + std::to_string(r.dim.ensemble));
  return r;
}

std::optional<DimRun> read_dim_run(const std::string& dir) {
  const std::string path = dir + "/" + kDimJson;
  std::error_code ec;
  if (!fs::exists(path, ec)) return std::nullopt;
  json j;
  try {
    j = json::parse(read_file_bytes(path));
  } catch (const json::exception&) {
    throw DataError(path + " is not valid JSON; delete the folder to start over");
  }
  return dim_run_from_json(j, path);
}

std::string dim_metrics_jsonl(const DimRun& r) {
  std::string out;
  for (const DimMember& m : r.members)
    if (m.finished)
      for (const auto& e : m.metrics) out += epoch_json(e).dump() + "\n";
  return out;
}

void refuse_other_method_folder(const std::string& dir, const std::string& method) {
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) return;
  std::vector<fs::path> records;
  for (const auto& entry : fs::directory_iterator(dir, ec))
    if (entry.path().extension() == ".json") records.push_back(entry.path());
  std::sort(records.begin(), records.end());
  for (const fs::path& p : records) {
    std::string other;
    try {
      json j = json::parse(read_file_bytes(p.string()));
      if (j.is_object() && j.contains("method") && j["method"].is_string())
        other = j["method"].get<std::string>();
    } catch (const std::exception&) {
      continue;  // not a run record: the caller's own checks decide
    }
    if (!other.empty() && other != method)
      throw ConfigError(dir + " holds a run of method '" + other + "' (" +
                        p.filename().string() + "), not '" + method +
                        "': use another folder");
  }
}

void dim_sample_positions(const PackedEpisode& e, int t, const DimSettings& d, float* past,
                          float* future) {
  const float* pose = e.pose.data();
  const double x0 = pose[3 * t], y0 = pose[3 * t + 1], h0 = pose[3 * t + 2];
  auto put = [&](int s, float* out) {
    double ex, ey;
    to_ego_frame(x0, y0, h0, pose[3 * s], pose[3 * s + 1], ex, ey);
    out[0] = static_cast<float>(ex);
    out[1] = static_cast<float>(ey);
  };
  for (int k = 0; k < d.past; ++k) put(std::max(0, t - (k + 1) * d.waypoint_step), past + 2 * k);
  for (int k = 0; k < d.horizon; ++k) put(t + (k + 1) * d.waypoint_step, future + 2 * k);
}

// ---- the planner -------------------------------------------------------------------------

struct DimPlanner::Impl {
  DimRun run;
  std::unique_ptr<DimEnsemble> ensemble;
  DimPlanOptions options;
  torch::Tensor frame;  // 1 x C x H x W, reused
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
  impl_->options = {d.plan_iterations, d.plan_lr, d.goal_weight, d.aggregation};
  impl_->frame = torch::zeros({1, no.channels, no.height, no.width});
}

DimPlanner::~DimPlanner() = default;

const DimRun& DimPlanner::run() const { return impl_->run; }

void DimPlanner::set_planning(const DimSettings& p) {
  impl_->options = {p.plan_iterations, p.plan_lr, p.goal_weight, p.aggregation};
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
  step.target_speed = implied_speed(pl.z, d.waypoint_step, impl_->run.input.dt);
  return step;
}

}  // namespace cd
