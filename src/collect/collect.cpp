#include "collect/collect.hpp"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <optional>
#include <sstream>

#include <nlohmann/json.hpp>

#include "core/build_parts.hpp"
#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "core/fault.hpp"
#include "core/job.hpp"
#include "device/device.hpp"
#include "inference/batched_inference.hpp"
#include "data/h5_io.hpp"
#include "data/h5_episode.hpp"
#include "runs/record.hpp"
#include "world/town.hpp"

namespace fs = std::filesystem;

namespace cd {

namespace {

constexpr int kMaxAttempts = 2;  // a worker that dies is retried once per episode

bool episode_complete(const std::string& path) {
  return h5::episode_complete(path, [](const std::string& p) { read_episode_meta(p); });
}

}  // namespace

std::string episode_file_name(int index) {
  char name[32];
  std::snprintf(name, sizeof name, "episode_%06d.h5", index);
  return name;
}

std::optional<nlohmann::json> recorded_collect_settings(const std::string& folder) {
  const std::string manifest = folder + "/collect.json";
  if (!fs::exists(manifest)) return std::nullopt;
  try {
    return nlohmann::json::parse(read_file_bytes(manifest)).at("settings");
  } catch (const std::exception& e) {
    throw DataError(manifest + " is damaged (" + e.what() + ")");
  }
}

CollectReport collect(const Settings& settings, const CollectOptions& options) {
  require_sumo("collect");
  resolve_network(settings.world.town);  // a bad town is one clear error, not one per worker
  const std::string& out = settings.collect.out;
  CollectReport report;
  // Each worker loads the network once; each episode runs in a fresh fork of it.
  std::unique_ptr<World> world;
  JobSpec spec;
  spec.command = "collect";
  spec.out = out;
  spec.total = settings.collect.episodes;
  spec.complete = [&](int i) { return episode_complete(out + "/" + episode_file_name(i)); };
  spec.label = "collect";
  // A finished folder (collect.json) collected with other settings is not added to: its
  // episodes and the new ones would mix two datasets. The episode count, workers and folder
  // may differ (a folder grows by a larger collect.episodes).
  spec.claim = [&] {
    const std::string manifest = out + "/collect.json";
    std::optional<nlohmann::json> recorded;
    try {
      recorded = recorded_collect_settings(out);
    } catch (const DataError& e) {
      throw DataError(std::string(e.what()) + ": collect into another --out folder");
    }
    if (!recorded) return;
    const nlohmann::json& stored = *recorded;
    // Keys the record lacks (written before they existed) read as their defaults, the behaviour
    // of their time: through settings_from_json, or, for a record it cannot read back (DAgger's
    // rollout folders hold derived seeds beyond a config's range), the record over the defaults.
    nlohmann::json then = settings_to_json(Settings{});
    then.merge_patch(stored);
    try {
      then = settings_to_json(settings_from_json(stored, manifest));
    } catch (const DataError&) {
    }
    // The frames too: a folder holds one view (sense.view) of one camera.
    const std::string diff = settings_diff(
        then, settings_to_json(settings), {"world", "ego", "expert", "bev", "sense", "collect"},
        [](const std::string& table, const std::string& key) {
          return table == "collect" && (key == "episodes" || key == "workers" || key == "out");
        });
    if (!diff.empty())
      throw ConfigError(out + " holds episodes collected with other settings (" + diff +
                        "): collect into another --out folder");
  };
  spec.quiet = options.quiet;
  spec.workers = settings.collect.workers;
  spec.attempts = kMaxAttempts;
  spec.failure_what = "collection";
  spec.setup = [&] { world = std::make_unique<World>(settings); };
  spec.run = [&](int i) {
    ExpertRecorder recorder(*world, settings);
    EpisodeData data;
    EpisodeMeta meta;
    std::string png = options.png_dir.empty()
                          ? ""
                          : options.png_dir + "/" + fs::path(episode_file_name(i)).stem().string();
    std::unique_ptr<Driver> driver = options.driver ? options.driver() : nullptr;
    EpisodeSummary s =
        recorder.run(i, episode_seed(settings.collect.seed, i), data, meta, png, driver.get());
    write_episode(out + "/" + episode_file_name(i), meta, data);
    // CAUSALDRIVE_INJECT_CRASH=collect:<i> (core/fault.hpp): kill -9 of the command and its workers.
    inject_crash("collect", i, out, CrashScope::ProcessGroup);
    return std::to_string(s.frames) + " " + s.outcome;
  };
  spec.done = [](int i, const std::string& note, std::string* line) {
    std::istringstream in(note);
    long f = 0;
    std::string outcome;
    in >> f >> outcome;
    *line = "episode " + std::to_string(i) + ": " + outcome;
    return f;
  };
  // The manifest (collect.json): the folder's commit, by rank 0 while it holds the lock.
  auto write_manifest = [&](const JobResult&) {
    nlohmann::json summary = nlohmann::json::array();
    for (int i = 0; i < settings.collect.episodes; ++i) {
      EpisodeMeta m = read_episode_meta(out + "/" + episode_file_name(i));
      EpisodeSummary s;
      s.index = i;
      s.outcome = m.outcome;
      auto get = [&](const char* k) {
        auto it = m.extra.find(k);
        return it == m.extra.end() ? std::string() : it->second;
      };
      s.route_length = std::atof(get("route_length_m").c_str());
      s.distance = std::atof(get("distance_m").c_str());
      s.red_light_violations = std::atoi(get("red_light_violations").c_str());
      s.collided_with = get("collided_with");
      report.episodes.push_back(s);
      summary.push_back({{"file", episode_file_name(i)},
                         {"outcome", s.outcome},
                         {"route_length_m", s.route_length},
                         {"distance_m", s.distance},
                         {"red_light_violations", s.red_light_violations},
                         {"collided_with", s.collided_with},
                         {"seed", m.seed}});
    }
    nlohmann::json manifest = {{"settings", settings_to_json(settings)}, {"episodes", summary}};
    write_file_atomic(out + "/collect.json", manifest.dump(2) + "\n");
  };
  std::optional<InputFormat> policy;
  if (!options.policy_checkpoint.empty()) policy = require_checkpoint(options.policy_checkpoint).input;
  const std::unique_ptr<BatchedInference> inference = start_job_inference(
      spec, settings.eval.batch,
      policy ? resolve_device(settings.eval.device, "eval.device") : std::string("cpu"),
      policy ? &*policy : nullptr);
  const JobResult job = run_job(spec, write_manifest);
  report.frames = job.units;
  report.recorded_now = job.run_now;
  report.seconds = job.seconds;
  return report;
}

}  // namespace cd
