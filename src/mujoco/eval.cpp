#include "mujoco/eval.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <memory>
#include <optional>

#include "device/device.hpp"
#include "core/build_parts.hpp"
#include "bench/runner.hpp"
#include "collect/expert_episode.hpp"
#include "bench/episode_files.hpp"
#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "core/rng.hpp"
#include "core/job.hpp"
#include "inference/batched_inference.hpp"
#include "data/mujoco_episode.hpp"
#include "datasets/episode_set.hpp"
#include "inference/policy_runner.hpp"
#include "mujoco/frame_policy.hpp"
#include "mujoco/env.hpp"
#include "mujoco/episode_note.hpp"
#include "runs/checkpoint.hpp"

namespace fs = std::filesystem;
using nlohmann::json;

namespace cd::mj {

namespace {

std::optional<json> load_record(const std::string& path) {
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) return std::nullopt;
  try {
    json j = json::parse(read_file_bytes(path));
    j.at("return").get<double>();
    j.at("length").get<int>();
    j.at("actions").get<std::vector<std::vector<float>>>();
    return j;
  } catch (const std::exception&) {
    return std::nullopt;  // damaged: run again
  }
}

// The agent's checks, one line each, before any work.
void validate(const EvalOptions& o, Checkpoint* ck) {
  if (o.out.empty()) throw ConfigError("eval --env needs an output folder (--out DIR)");
  if (o.episodes < 1) throw ConfigError("eval: --episodes must be at least 1");
  if (o.max_steps < 0) throw ConfigError("eval: --max-steps must not be negative");
  Env probe(o.env);  // unknown env or missing model file
  if (o.agent == "expert" || o.agent == "random") {
    if (!o.checkpoint.empty())
      throw ConfigError("agent '" + o.agent + "' takes no --checkpoint");
    // A trained expert's file is checked before any worker starts.
    if (o.agent == "expert" && !o.expert_policies.empty())
      make_expert(o.env, o.planner, o.expert_policies);
    return;
  }
  if (!is_policy_runner_method(o.agent))
    throw ConfigError("unknown agent '" + o.agent + "' for eval --env (expert, random, bc-so, "
                      "bc-oh, residual, fca, keyframe, hd, dagger)");
  if (o.checkpoint.empty())
    throw ConfigError("agent '" + o.agent + "' needs --checkpoint DIR (the output of "
                      "`causaldrive train --method " + o.agent + "` on MuJoCo-Image data)");
  *ck = require_checkpoint(o.checkpoint);
  if (ck->method != o.agent)
    throw ConfigError("checkpoint " + o.checkpoint + " was trained with method '" + ck->method +
                      "', not '" + o.agent + "'");
  if (ck->input.domain != kMujocoDomain)
    throw ConfigError("checkpoint " + o.checkpoint + " was trained on driving data; eval --env "
                      "runs checkpoints trained on MuJoCo-Image data");
  if (ck->input.env != o.env || ck->input.action_dim != probe.action_dim() ||
      ck->input.channels != probe.channels())
    throw ConfigError("checkpoint " + o.checkpoint + " was trained on '" + ck->input.env +
                      "' (" + std::to_string(ck->input.action_dim) + " actions); --env " +
                      o.env + " has " + std::to_string(probe.action_dim()));
}

// One episode; its record (return, length, outcome, the actions the agent chose). With `rec`,
// also the episode as the agent drove it (eval --record): each step's frame before the action
// (at the policy's size for a policy), state, the action executed, reward.
json run_episode(const EvalOptions& o, int index, MujocoEpisode* rec) {
  const uint64_t seed = episode_seed(derive_seed(o.seed, kEvalStream), index);
  std::unique_ptr<FramePolicy> policy;
  EnvOptions env_options;
  if (is_policy_runner_method(o.agent)) {
    policy = std::make_unique<FramePolicy>(o.checkpoint, o.agent, o.device);
    env_options.width = policy->width();
    env_options.height = policy->height();
  }
  Env env(o.env, env_options);
  const int A = env.action_dim();
  const std::vector<double> low = env.action_low(), high = env.action_high();
  const int limit = o.max_steps > 0 ? std::min(o.max_steps, env.max_steps()) : env.max_steps();
  std::unique_ptr<Expert> expert;
  if (o.agent == "expert") {
    PlannerOptions planner = o.planner;
    planner.seed = derive_seed(seed, 1);
    expert = make_expert(o.env, planner, o.expert_policies);
  }
  Rng rng(derive_seed(seed, 3));

  Frame current = env.reset(seed);
  if (policy) policy->push(rec ? current : std::move(current));
  if (rec) {
    *rec = MujocoEpisode{};
    rec->env = o.env;
    rec->seed = seed;
    rec->dt = env.dt();
    rec->frame_skip = env.frame_skip();
    rec->height = env_options.height;
    rec->width = env_options.width;
    rec->action_dim = A;
  }
  std::vector<double> action(static_cast<size_t>(A), 0.0);
  std::vector<float> chosen;
  double ret = 0;
  int steps = 0;
  std::string outcome = "truncated";
  for (int t = 0; t < limit; ++t) {
    // A policy acts once its history holds real frames; until then the zero action (prefill).
    const bool acts = !policy || policy->ready();
    if (acts) {
      if (policy) {
        action = policy->act(action, low, high);
      } else if (expert) {
        action = expert->act(env.state());
      } else {
        for (int j = 0; j < A; ++j) action[j] = rng.uniform(low[j], high[j]);
      }
      for (double v : action) chosen.push_back(static_cast<float>(v));
    }
    if (rec) {
      const std::vector<double> state = env.state();
      rec->state_dim = static_cast<int>(state.size());
      rec->obs.insert(rec->obs.end(), current.begin(), current.end());
      for (double v : state) rec->state.push_back(static_cast<float>(v));
      for (double v : action) rec->action.push_back(static_cast<float>(v));
      rec->noise.push_back(0);
    }
    const StepResult r = env.step(action);
    ret += r.reward;
    ++steps;
    if (rec) rec->reward.push_back(static_cast<float>(r.reward));
    if (r.terminated) {
      outcome = "terminated";
      break;
    }
    if (policy || rec) current = env.render();
    if (policy) policy->push(rec ? current : std::move(current));
  }
  if (rec) {
    rec->outcome = outcome;
    rec->episode_return = ret;
    rec->extra["agent"] = o.agent;
    rec->extra["label"] = o.label.empty() ? o.agent : o.label;
    rec->extra["action_source"] = "agent";
  }
  json actions = json::array();
  for (size_t i = 0; i < chosen.size(); i += A)
    actions.push_back(std::vector<float>(chosen.begin() + i, chosen.begin() + i + A));
  return {{"index", index}, {"seed", seed},       {"return", ret},
          {"length", steps}, {"outcome", outcome}, {"actions", actions}};
}

// The expert's labels of a checkpoint's training data, one T x A block per episode: its data
// folder, or several joined by " + " (dagger's aggregate: the expert data and its rollouts).
std::vector<std::vector<float>> data_actions(const std::string& dirs) {
  std::vector<std::vector<float>> out;
  size_t start = 0;
  while (start <= dirs.size()) {
    size_t end = dirs.find(" + ", start);
    if (end == std::string::npos) end = dirs.size();
    for (const std::string& path : list_episode_files(dirs.substr(start, end - start)))
      out.push_back(read_mujoco_episode(path).action);
    start = end + 3;
  }
  return out;
}

json r2_json(double r2) { return std::isfinite(r2) ? json(r2) : json(nullptr); }

}  // namespace

double lag1_r2(const std::vector<std::vector<float>>& episodes, int A) {
  const int n = A + 1;  // [a_{t-1}, 1]
  std::vector<double> G(static_cast<size_t>(n) * n, 0.0), H(static_cast<size_t>(n) * A, 0.0);
  std::vector<double> sum(A, 0.0), sum2(A, 0.0);
  long pairs = 0;
  std::vector<double> x(n);
  for (const auto& e : episodes) {
    const size_t T = e.size() / A;
    for (size_t t = 1; t < T; ++t) {
      for (int j = 0; j < A; ++j) x[j] = e[(t - 1) * A + j];
      x[A] = 1.0;
      for (int a = 0; a < n; ++a) {
        for (int b = 0; b < n; ++b) G[a * n + b] += x[a] * x[b];
        for (int j = 0; j < A; ++j) H[a * A + j] += x[a] * e[t * A + j];
      }
      for (int j = 0; j < A; ++j) {
        sum[j] += e[t * A + j];
        sum2[j] += static_cast<double>(e[t * A + j]) * e[t * A + j];
      }
      ++pairs;
    }
  }
  const double nan = std::numeric_limits<double>::quiet_NaN();
  if (pairs < A + 2) return nan;
  double sst = 0;
  for (int j = 0; j < A; ++j) sst += sum2[j] - sum[j] * sum[j] / pairs;
  if (!(sst > 1e-12)) return nan;
  // W = G^-1 H (Gauss-Jordan, partial pivoting; a tiny ridge keeps repeated columns solvable).
  double trace = 0;
  for (int a = 0; a < n; ++a) trace += G[a * n + a];
  for (int a = 0; a < n; ++a) G[a * n + a] += 1e-12 * trace;
  std::vector<double> W = H;
  for (int c = 0; c < n; ++c) {
    int p = c;
    for (int r = c + 1; r < n; ++r)
      if (std::abs(G[r * n + c]) > std::abs(G[p * n + c])) p = r;
    if (std::abs(G[p * n + c]) < 1e-300) return nan;
    if (p != c) {
      for (int k = 0; k < n; ++k) std::swap(G[c * n + k], G[p * n + k]);
      for (int j = 0; j < A; ++j) std::swap(W[c * A + j], W[p * A + j]);
    }
    const double d = G[c * n + c];
    for (int k = 0; k < n; ++k) G[c * n + k] /= d;
    for (int j = 0; j < A; ++j) W[c * A + j] /= d;
    for (int r = 0; r < n; ++r) {
      if (r == c || G[r * n + c] == 0) continue;
      const double f = G[r * n + c];
      for (int k = 0; k < n; ++k) G[r * n + k] -= f * G[c * n + k];
      for (int j = 0; j < A; ++j) W[r * A + j] -= f * W[c * A + j];
    }
  }
  double sse = 0;
  for (const auto& e : episodes) {
    const size_t T = e.size() / A;
    for (size_t t = 1; t < T; ++t) {
      for (int j = 0; j < A; ++j) {
        double pred = W[A * A + j];
        for (int a = 0; a < A; ++a) pred += e[(t - 1) * A + a] * W[a * A + j];
        const double d = e[t * A + j] - pred;
        sse += d * d;
      }
    }
  }
  return 1.0 - sse / sst;
}

EvalReport evaluate(const EvalOptions& o) {
  require_mujoco("eval of a MuJoCo-Image run");
  // Its one-line error before any worker; the device the run is on is part of its claim.
  const std::string device = resolve_device(o.device, "eval.device");
  Checkpoint ck;
  validate(o, &ck);
  const std::string ep_dir = o.out + "/episodes";
  json run = {{"agent", o.agent},
                    {"label", o.label.empty() ? o.agent : o.label},
                    {"env", o.env},
                    {"checkpoint", o.checkpoint},
                    {"seed", o.seed},
                    {"max_steps", o.max_steps},
                    {"device", device}};
  std::vector<json> records(o.episodes);
  EvalReport report;
  JobSpec spec;
  spec.command = "eval";
  spec.out = o.out;
  spec.subfolders = {"episodes"};
  // Folders written before the device was recorded ran on the CPU.
  spec.claim = [&] {
    claim_eval_folder(o.out, run,
                      {"agent", "env", "checkpoint", "seed", "max_steps", "device", "inference"},
                      [](json& prev) {
                        if (!prev.contains("device")) prev["device"] = "cpu";
                        if (!prev.contains("inference")) prev["inference"] = "batch-1";
                      });
  };
  spec.total = o.episodes;
  spec.complete = [&](int i) {
    auto r = load_record(ep_dir + "/" + episode_record_name(i));
    if (r) records[i] = *r;
    return r.has_value();
  };
  spec.label = "eval " + o.agent + " on " + o.env;
  spec.quiet = o.quiet;
  spec.workers = std::max(1, o.workers);
  spec.attempts = o.max_attempts;
  spec.failure_what = "eval";
  // Each episode in a fresh fork: its env, GL context and networks are made there.
  spec.run = [&](int i) {
    MujocoEpisode recording;
    const json r = run_episode(o, i, o.record ? &recording : nullptr);
    // The recording first: the record commits the episode.
    if (o.record) write_mujoco_episode(ep_dir + "/" + episode_recording_name(i), recording);
    write_file_atomic(ep_dir + "/" + episode_record_name(i), r.dump() + "\n");
    return EpisodeNote{r.at("length").get<long>(), r.at("return").get<double>()}.encode();
  };
  spec.done = [](int i, const std::string& note, std::string* line) {
    const EpisodeNote n = EpisodeNote::decode(note);
    *line = n.progress_line(i);
    return n.steps;
  };
  // results.json: the folder's commit, by rank 0 while it holds the lock.
  auto write_results = [&](const JobResult& job) {
    for (int i : job.todo) {
      auto r = load_record(ep_dir + "/" + episode_record_name(i));
      if (!r)
        throw DataError("episode record " + episode_record_name(i) + " is missing after its run");
      records[i] = *r;
    }
    json episodes = json::array();
    std::vector<std::vector<float>> chosen;
    double sum = 0, sum_len = 0;
    for (const json& r : records) {
      episodes.push_back({{"index", r.at("index")},
                          {"seed", r.at("seed")},
                          {"return", r.at("return")},
                          {"length", r.at("length")},
                          {"outcome", r.at("outcome")}});
      sum += r.at("return").get<double>();
      sum_len += r.at("length").get<int>();
      std::vector<float> flat;
      for (const auto& a : r.at("actions")) {
        const auto v = a.get<std::vector<float>>();
        flat.insert(flat.end(), v.begin(), v.end());
      }
      chosen.push_back(std::move(flat));
    }
    const double n = static_cast<double>(records.size());
    const double mean = sum / n;
    double var = 0;
    for (const json& r : records) var += std::pow(r.at("return").get<double>() - mean, 2);
    const double sd = records.size() > 1 ? std::sqrt(var / (n - 1)) : 0.0;
    const int A = Env(o.env).action_dim();
    json copycat = {
        {"definition",
         "R^2 of the least-squares linear prediction of a_t from a_{t-1} (a_t ~ W a_{t-1} + b, "
         "pairs within episodes, pooled over components); policy: the actions it chose here, "
         "expert data: the recorded labels of the checkpoint's training data"},
        {"policy_r2", r2_json(lag1_r2(chosen, A))},
        {"expert_data_r2", ck.data_dir.empty() ? json(nullptr)
                                                : r2_json(lag1_r2(data_actions(ck.data_dir), A))}};
    report.results = run;
    report.results["episodes"] = episodes;
    report.results["summary"] = {{"episodes", records.size()},
                                 {"mean_return", mean},
                                 {"std_return", sd},
                                 {"mean_length", sum_len / n},
                                 {"copycat_policy_r2", copycat["policy_r2"]},
                                 {"copycat_expert_r2", copycat["expert_data_r2"]}};
    report.results["copycat"] = copycat;
    write_file_atomic(o.out + "/results.json", report.results.dump(2) + "\n");
  };
  const std::unique_ptr<BatchedInference> inference =
      start_job_inference(spec, o.batch, device,
                          is_policy_runner_method(o.agent) ? &ck.input : nullptr);
  run["inference"] = inference_record(inference.get(), device);
  const JobResult job = run_job(spec, write_results);
  report.steps = job.units;
  report.run_now = job.run_now;
  report.seconds = job.seconds;
  return report;
}

std::string eval_table(const json& res) {
  const json& s = res.at("summary");
  const json& c = res.at("copycat");
  auto r2 = [](const json& v) {
    if (v.is_null()) return std::string("-");
    char b[32];
    std::snprintf(b, sizeof b, "%.3f", v.get<double>());
    return std::string(b);
  };
  char row[256];
  std::snprintf(row, sizeof row, "| %s | %s | %d | %.1f ± %.1f | %.1f | %s / %s |\n",
                res.at("agent").get<std::string>().c_str(), res.at("env").get<std::string>().c_str(),
                s.at("episodes").get<int>(), s.at("mean_return").get<double>(),
                s.at("std_return").get<double>(), s.at("mean_length").get<double>(),
                r2(c.at("policy_r2")).c_str(), r2(c.at("expert_data_r2")).c_str());
  return "| agent | env | episodes | return (mean ± sd) | mean length | copycat R² policy / "
         "expert data |\n|---|---|---|---|---|---|\n" + std::string(row);
}

}  // namespace cd::mj
