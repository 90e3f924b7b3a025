#include "runs/dim_run.hpp"

#include <algorithm>
#include <filesystem>

#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "runs/record.hpp"

namespace cd {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {


json epoch_json(const DimEpochMetrics& m) {
  json j = epoch_metrics_json(m, "nll");
  j["member"] = m.member;
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
          {"runtime", r.runtime},
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
  r.dim = settings_from_json(r.settings, where).dim;
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
  if (j.contains("runtime")) r.runtime = j.at("runtime");
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
      DimEpochMetrics em;
      static_cast<EpochMetrics&>(em) = epoch_metrics_from_json(ej, "nll", where);
      em.member = JsonFields{ej, where}.get<int>("member");
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

}  // namespace cd
