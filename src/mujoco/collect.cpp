#include "mujoco/collect.hpp"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <optional>

#include <nlohmann/json.hpp>

#include "core/build_parts.hpp"
#include "collect/collect.hpp"
#include "collect/expert_episode.hpp"
#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "core/job.hpp"
#include "inference/batched_inference.hpp"
#include "data/h5_io.hpp"
#include "mujoco/episode_note.hpp"

namespace fs = std::filesystem;

namespace cd::mj {

namespace {

constexpr int kMaxAttempts = 2;  // a worker that dies is retried once per episode

bool episode_complete(const std::string& path) {
  return h5::episode_complete(path, [](const std::string& p) { read_mujoco_episode_meta(p); });
}

void validate(const CollectOptions& o) {
  env_spec(o.env);  // an unknown env: one line, before any work
  if (o.out.empty()) throw ConfigError("collect --env needs an output folder (--out DIR)");
  if (o.episodes < 1) throw ConfigError("collect: --episodes must be at least 1");
  if (o.workers < 1) throw ConfigError("collect: --workers must be at least 1");
  if (o.max_steps < 0) throw ConfigError("collect: --max-steps must not be negative");
  const NoiseOptions& n = o.noise;
  if (n.rate < 0 || n.rate > 1 || n.min_steps < 1 || n.max_steps < n.min_steps || n.sigma < 0)
    throw ConfigError("collect: noise settings out of range");
  if (o.driver && n.enabled)
    throw ConfigError("collect: noise injection and a driver exclude each other");
  // A trained expert is loaded here once, so that a missing or wrong file is one line before
  // any worker starts.
  if (!o.expert_policies.empty()) make_expert(o.env, o.planner, o.expert_policies);
}

}  // namespace

MujocoEpisode record_episode(const CollectOptions& o, int index) {
  const uint64_t seed = episode_seed(o.seed, index);
  EnvOptions env_options;
  env_options.width = o.width;
  env_options.height = o.height;
  Env env(o.env, env_options);
  PlannerOptions planner = o.planner;
  planner.seed = derive_seed(seed, 1);
  const std::unique_ptr<Expert> expert_ptr = make_expert(o.env, planner, o.expert_policies);
  Expert& expert = *expert_ptr;
  Rng noise_rng(derive_seed(seed, 2));
  const std::vector<double> low = env.action_low(), high = env.action_high();
  const int limit = o.max_steps > 0 ? std::min(o.max_steps, env.max_steps()) : env.max_steps();

  MujocoEpisode e;
  e.env = o.env;
  e.seed = seed;
  e.dt = env.dt();
  e.frame_skip = env.frame_skip();
  e.channels = env.channels();
  e.height = env.height();
  e.width = env.width();
  e.action_dim = env.action_dim();
  e.state_dim = env.state_dim();
  e.extra["expert"] = expert.describe();
  char noise_line[128];
  std::snprintf(noise_line, sizeof noise_line, "%s rate=%g steps=%d..%d sigma=%g",
                o.noise.enabled ? "on" : "off", o.noise.rate, o.noise.min_steps,
                o.noise.max_steps, o.noise.sigma);
  e.extra["noise_injection"] = noise_line;
  std::unique_ptr<Driver> driver = o.driver ? o.driver() : nullptr;
  if (driver) {
    driver->begin_episode(seed);
    e.extra["driver"] = driver->describe();
  }

  Frame frame = env.reset(seed);
  int noise_left = 0;
  for (int t = 0; t < limit; ++t) {
    const std::vector<double> state = env.state();
    const std::vector<double> label = expert.act(state);
    std::vector<double> executed = driver ? driver->drive(frame, label) : label;
    if (o.noise.enabled) {
      if (noise_left == 0 && noise_rng.uniform() < o.noise.rate) {
        noise_left = o.noise.min_steps +
                     static_cast<int>(noise_rng.below(o.noise.max_steps - o.noise.min_steps + 1));
      }
      if (noise_left > 0) {
        for (size_t j = 0; j < executed.size(); ++j) {
          const double half = 0.5 * (high[j] - low[j]);
          executed[j] = std::clamp(executed[j] + o.noise.sigma * half * standard_normal(noise_rng),
                                   low[j], high[j]);
        }
        --noise_left;
        e.noise.push_back(1);
      } else {
        e.noise.push_back(0);
      }
    } else {
      e.noise.push_back(executed == label ? 0 : 1);
    }
    e.obs.insert(e.obs.end(), frame.begin(), frame.end());
    for (double v : state) e.state.push_back(static_cast<float>(v));
    for (double v : label) e.action.push_back(static_cast<float>(v));
    const StepResult r = env.step(executed);
    e.reward.push_back(static_cast<float>(r.reward));
    e.episode_return += r.reward;
    if (r.terminated) {
      e.outcome = "terminated";
      break;
    }
    env.render(frame.data());
  }
  if (e.outcome.empty()) e.outcome = "truncated";
  return e;
}

CollectReport collect(const CollectOptions& o) {
  require_mujoco("collect --env");
  validate(o);
  { Env probe(o.env); }  // a missing model file: one line, before any worker starts
  CollectReport report;
  JobSpec spec;
  spec.command = "collect";
  spec.out = o.out;
  spec.total = o.episodes;
  spec.complete = [&](int i) { return episode_complete(o.out + "/" + episode_file_name(i)); };
  spec.label = "collect " + o.env;
  spec.quiet = o.quiet;
  spec.workers = o.workers;
  spec.attempts = kMaxAttempts;
  spec.failure_what = "collection";
  // Each episode runs in a fresh fork: its env and GL context are made there, never inherited.
  spec.run = [&](int i) {
    MujocoEpisode e = record_episode(o, i);
    write_mujoco_episode(o.out + "/" + episode_file_name(i), e);
    return EpisodeNote{static_cast<long>(e.frames()), e.episode_return}.encode();
  };
  spec.done = [](int i, const std::string& note, std::string* line) {
    const EpisodeNote n = EpisodeNote::decode(note);
    *line = n.progress_line(i);
    return n.steps;
  };
  // The manifest (collect.json): the folder's commit, by rank 0 while it holds the lock.
  auto write_manifest = [&](const JobResult&) {
    nlohmann::json episodes = nlohmann::json::array();
    for (int i = 0; i < o.episodes; ++i) {
      const MujocoEpisode m = read_mujoco_episode_meta(o.out + "/" + episode_file_name(i));
      report.returns.push_back(m.episode_return);
      episodes.push_back({{"file", episode_file_name(i)},
                          {"seed", m.seed},
                          {"outcome", m.outcome},
                          {"return", m.episode_return}});
    }
    report.episodes = o.episodes;
    nlohmann::json manifest = {{"env", o.env},
                               {"seed", o.seed},
                               {"episodes", episodes},
                               {"width", o.width},
                               {"height", o.height},
                               {"max_steps", o.max_steps},
                               {"noise", o.noise.enabled}};
    write_file_atomic(o.out + "/collect.json", manifest.dump(2) + "\n");
  };
  std::optional<InputFormat> policy;
  if (!o.policy_checkpoint.empty()) policy = require_checkpoint(o.policy_checkpoint).input;
  const std::unique_ptr<BatchedInference> inference =
      start_job_inference(spec, o.batch, o.device, policy ? &*policy : nullptr);
  const JobResult job = run_job(spec, write_manifest);
  report.frames = job.units;
  report.recorded_now = job.run_now;
  report.seconds = job.seconds;
  return report;
}

}  // namespace cd::mj
