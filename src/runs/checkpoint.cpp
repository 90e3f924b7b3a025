#include "runs/checkpoint.hpp"

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>

#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "runs/record.hpp"

namespace cd {

namespace fs = std::filesystem;
using nlohmann::json;

json checkpoint_to_json(const Checkpoint& c) {
  json metrics = json::array();
  for (const auto& m : c.metrics) metrics.push_back(epoch_metrics_json(m, "loss"));
  json j = {
      {"format", "causaldrive-checkpoint"},
      {"version", kCheckpointVersion},
      {"method", c.method},
      {"settings", c.settings},
      {"input",
       {{"channels", c.input.channels},
        {"height", c.input.height},
        {"width", c.input.width},
        {"history", c.input.history},
        {"stride", c.input.stride},
        {"dt", c.input.dt},
        {"metres_per_pixel", c.input.metres_per_pixel},
        {"channel_names", c.input.channel_names}}},
      {"data", c.data_dir},
      {"samples", {{"train", c.train_samples}, {"val", c.val_samples}}},
      {"episodes", {{"train", c.train_episodes}, {"val", c.val_episodes}}},
      {"device", c.device},
      {"epochs_done", c.epochs_done},
      {"best_epoch", c.best_epoch},
      {"best_loss", c.best_loss},
      {"lr", c.lr},
      {"bad_epochs", c.bad_epochs},
      {"metrics", metrics},
  };
  if (c.input.action_dim != 2) j["input"]["action_dim"] = c.input.action_dim;
  if (c.input.domain != "driving") {
    j["input"]["domain"] = c.input.domain;
    j["input"]["env"] = c.input.env;
  }
  if (!c.input.action_output.empty()) j["input"]["action_output"] = c.input.action_output;
  if (!c.val_files.empty()) j["episodes"]["val_files"] = c.val_files;
  if (!c.method_record.is_null()) j["method_record"] = c.method_record;
  if (!c.runtime.is_null()) j["runtime"] = c.runtime;
  return j;
}

Checkpoint checkpoint_from_json(const json& j, const std::string& where) {
  JsonFields f{j, where};
  if (f.get<std::string>("format") != "causaldrive-checkpoint")
    throw DataError(where + ": not a causaldrive checkpoint");
  if (int v = f.get<int>("version"); v != kCheckpointVersion)
    throw DataError(where + ": checkpoint version " + std::to_string(v) + " (this build reads " +
                    std::to_string(kCheckpointVersion) + ")");
  Checkpoint c;
  c.method = f.get<std::string>("method");
  c.settings = f.at("settings");
  {
    const Settings s = settings_from_json(c.settings, where);
    c.model = s.model;
    c.residual = s.residual;
    c.fca = s.fca;
  }
  JsonFields in{f.at("input"), where};
  c.input.channels = in.get<int>("channels");
  c.input.height = in.get<int>("height");
  c.input.width = in.get<int>("width");
  c.input.history = in.get<int>("history");
  c.input.stride = in.get<int>("stride");
  c.input.dt = in.get<double>("dt");
  c.input.metres_per_pixel = in.get<double>("metres_per_pixel");
  c.input.channel_names = in.get<std::vector<std::string>>("channel_names");
  if (f.at("input").contains("action_dim")) c.input.action_dim = in.get<int>("action_dim");
  if (f.at("input").contains("domain")) {
    c.input.domain = in.get<std::string>("domain");
    c.input.env = in.get<std::string>("env");
    if (c.input.domain != "mujoco") throw DataError(where + ": unknown input domain '" + c.input.domain + "'");
  }
  if (f.at("input").contains("action_output"))
    c.input.action_output = in.get<std::string>("action_output");
  else if (c.input.domain == "mujoco" || c.input.action_dim != 2)
    throw DataError(where + ": trained by an earlier build whose policy squashed every action "
                    "with a sigmoid, so it never output a negative " +
                    std::string(c.input.domain == "mujoco" ? "action" : "steer") +
                    ": retrain it into a new folder");
  if (j.contains("method_record")) c.method_record = j.at("method_record");
  if (c.input.channels < 1 || c.input.height < 1 || c.input.width < 1 || c.input.history < 1 ||
      c.input.stride < 1 || c.input.action_dim < 1)
    throw DataError(where + ": input format out of range");
  c.data_dir = f.get<std::string>("data");
  JsonFields samples{f.at("samples"), where}, episodes{f.at("episodes"), where};
  c.train_samples = samples.get<long>("train");
  c.val_samples = samples.get<long>("val");
  c.train_episodes = episodes.get<int>("train");
  c.val_episodes = episodes.get<int>("val");
  if (f.at("episodes").contains("val_files"))
    c.val_files = episodes.get<std::vector<std::string>>("val_files");
  c.device = f.get<std::string>("device");
  if (j.contains("runtime")) c.runtime = j.at("runtime");
  c.epochs_done = f.get<int>("epochs_done");
  c.best_epoch = f.get<int>("best_epoch");
  c.best_loss = f.get<double>("best_loss");
  c.lr = f.get<double>("lr");
  c.bad_epochs = f.get<int>("bad_epochs");
  const json& metrics = f.at("metrics");
  if (!metrics.is_array()) throw DataError(where + ": 'metrics' is not an array");
  for (const json& mj : metrics) {
    c.metrics.push_back(epoch_metrics_from_json(mj, "loss", where));
  }
  if (static_cast<int>(c.metrics.size()) != c.epochs_done)
    throw DataError(where + ": " + std::to_string(c.metrics.size()) + " metric lines for " +
                    std::to_string(c.epochs_done) + " epochs");
  return c;
}

std::optional<Checkpoint> read_checkpoint(const std::string& dir) {
  const std::string path = (fs::path(dir) / kCheckpointJson).string();
  std::error_code ec;
  if (!fs::exists(path, ec)) return std::nullopt;
  json j;
  try {
    j = json::parse(read_file_bytes(path));
  } catch (const json::exception& e) {
    throw DataError(path + " is not valid JSON (" + std::string(e.what()) + ")");
  }
  return checkpoint_from_json(j, path);
}

Checkpoint require_checkpoint(const std::string& dir) {
  std::error_code ec;
  if (!fs::is_directory(dir, ec))
    throw DataError("checkpoint folder '" + dir + "' not found (write one with `causaldrive "
                    "train --out DIR`)");
  auto c = read_checkpoint(dir);
  if (!c)
    throw DataError("'" + dir + "' holds no " + kCheckpointJson +
                    " (not a finished `causaldrive train` folder)");
  if (c->epochs_done < 1 || c->best_epoch < 1)
    throw DataError(dir + "/" + kCheckpointJson + " records no finished epoch");
  return *c;
}

std::string metrics_jsonl(const Checkpoint& c) {
  std::string out;
  for (const auto& m : c.metrics) out += epoch_metrics_json(m, "loss").dump() + "\n";
  return out;
}

std::string pending_name(const std::string& final_name, int epoch) {
  char tag[32];
  std::snprintf(tag, sizeof tag, ".e%06d.pending", epoch);
  return final_name + tag;
}

int settle_pending_files(const std::string& dir, int committed) {
  // Only names this code writes are touched: an --out folder may hold the user's own files.
  auto ours = [](const std::string& name) {
    for (const char* f : {kModelFile, kBestFile, kOptimizerFile, kCheckpointJson, kMetricsJsonl})
      if (name.rfind(std::string(f) + ".", 0) == 0) return true;
    return false;
  };
  int rolled = 0;
  std::error_code ec;
  std::vector<fs::path> entries;
  for (const auto& e : fs::directory_iterator(dir, ec)) entries.push_back(e.path());
  for (const fs::path& p : entries) {
    const std::string name = p.filename().string();
    if (!ours(name)) continue;
    if (name.ends_with(".tmp")) {  // an unfinished atomic write
      fs::remove(p, ec);
      continue;
    }
    if (!name.ends_with(".pending")) continue;
    bool rolled_forward = false;
    for (const char* final_name : {kModelFile, kBestFile, kOptimizerFile}) {
      if (name != pending_name(final_name, committed)) continue;
      fs::rename(p, fs::path(dir) / final_name, ec);
      if (ec) throw IoError("cannot rename " + p.string() + ": " + ec.message());
      rolled_forward = true;
      ++rolled;
    }
    if (!rolled_forward) fs::remove(p, ec);
  }
  return rolled;
}

}  // namespace cd
