// dagger (Ross, Gordon and Bagnell 2011): dataset aggregation with the expert's labels in
// closed loop. Iteration 0 trains the bc-oh policy on the expert data. Iteration i >= 1 drives
// dagger.episodes episodes in dagger.town / dagger.traffic on random routes drawn from
// dagger.seed (never a suite's tasks) with the policy of iteration i-1 mixed with the expert:
// each step executes the expert's control with probability beta_i = beta * beta_decay^(i-1),
// the policy's otherwise; every visited state is recorded with the expert's action as its
// label. The policy is then trained further (warm start, dagger.epochs epochs) on the expert
// data plus every rollout so far.
// On MuJoCo-Image data the rounds drive the data's env instead (episodes from dagger.seed, at
// the data's frame size, with [mujoco]'s workers, step limit and planner); the planner expert
// labels every visited state and acts until the policy's history holds real frames.
//
// Run folder:
//   iter_00/ .. iter_NN/     each iteration's policy (a family run folder, resumable)
//   rollouts_01/ ..          each iteration's closed-loop episodes (a collect folder, resumable)
//   dagger.json              the record: per iteration its beta, episodes, expert labels,
//                            outcomes; written after each iteration (the commit)
//   checkpoint.json, best.pt, model.pt, metrics.jsonl
//                            the last iteration's run, copied when all are done: what the
//                            agent, the probe and report load
// A run stopped anywhere resumes at its last finished step (the iteration's collect and
// training resume themselves).
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>

#include "agents/observation_feed.hpp"
#include "collect/collect.hpp"
#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "core/fault.hpp"
#include "core/progress.hpp"
#include "core/rng.hpp"
#include "data/h5_episode.hpp"
#include "data/mujoco_episode.hpp"
#include "datasets/episode_set.hpp"
#include "methods/policy_family.hpp"
#include "mujoco/collect.hpp"
#include "mujoco/frame_policy.hpp"
#include "mujoco/expert.hpp"
#include "runs/checkpoint.hpp"
#include "world/world.hpp"

namespace cd {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

constexpr const char* kDaggerJson = "dagger.json";
constexpr uint64_t kMixStream = 3;

std::string iteration_dir(const std::string& out, int i) {
  char name[32];
  std::snprintf(name, sizeof name, "/iter_%02d", i);
  return out + name;
}

std::string rollout_dir(const std::string& out, int i) {
  char name[32];
  std::snprintf(name, sizeof name, "/rollouts_%02d", i);
  return out + name;
}

// What a rollout's file records of who drove it.
std::string describe_mix(double beta, const std::string& policy_dir) {
  char b[96];
  std::snprintf(b, sizeof b, "dagger beta %.4f, policy ", beta);
  return b + policy_dir;
}

// The policy of a finished iteration, mixed with the expert.
class DaggerDriver : public Driver {
 public:
  DaggerDriver(std::string policy_dir, const Settings& s, double beta)
      : dir_(std::move(policy_dir)), settings_(s), beta_(beta) {}

  void begin_episode(World& world, uint64_t episode_seed) override {
    if (!agent_) agent_ = load_policy_family_agent("dagger", dir_, settings_, nullptr);
    agent_->begin_episode();
    feed_.emplace(world, *agent_);
    rng_ = Rng(derive_seed(episode_seed, kMixStream));
  }

  Control drive(const Control& expert) override {
    feed_->push();
    // The expert drives until the policy has a full history of real frames.
    if (!feed_->ready()) return expert;
    const Control policy = agent_->act(feed_->observe());
    return rng_.uniform() < beta_ ? expert : policy;
  }

  std::string describe() const override { return describe_mix(beta_, dir_); }

 private:
  std::string dir_;
  Settings settings_;
  double beta_;
  std::unique_ptr<Agent> agent_;
  std::optional<ObservationFeed> feed_;
  Rng rng_{0};
};

// The MuJoCo-Image counterpart: the policy on rendered frames; the expert acts until the
// policy's history holds real frames.
class MujocoDaggerDriver : public mj::Driver {
 public:
  MujocoDaggerDriver(std::string policy_dir, const std::string& env, double beta)
      : dir_(std::move(policy_dir)), beta_(beta) {
    mj::Env probe(env);
    low_ = probe.action_low();
    high_ = probe.action_high();
  }

  void begin_episode(uint64_t episode_seed) override {
    if (!policy_) policy_ = std::make_unique<mj::FramePolicy>(dir_, "dagger");
    policy_->begin_episode();
    previous_.assign(low_.size(), 0.0);
    rng_ = Rng(derive_seed(episode_seed, kMixStream));
  }

  std::vector<double> drive(const mj::Frame& frame, const std::vector<double>& expert) override {
    policy_->push(frame);
    std::vector<double> executed = expert;
    if (policy_->ready()) {
      std::vector<double> policy = policy_->act(previous_, low_, high_);
      if (!(rng_.uniform() < beta_)) executed = std::move(policy);
    }
    previous_ = executed;
    return executed;
  }

  std::string describe() const override { return describe_mix(beta_, dir_); }

 private:
  std::string dir_;
  double beta_;
  std::vector<double> low_, high_, previous_;
  std::unique_ptr<mj::FramePolicy> policy_;
  Rng rng_{0};
};

// One iteration's closed-loop episodes, recorded into `out` (resumable): the frames labelled by
// the expert and the episodes' outcomes.
struct Rollouts {
  long frames = 0;
  std::map<std::string, int> outcomes;
};

Rollouts driving_rollouts(const Settings& settings, int i, const std::string& policy,
                          double beta, const std::string& out, bool quiet) {
  const DaggerSettings& d = settings.dagger;
  Settings cs = settings;
  cs.world.town = d.town;
  cs.world.traffic = d.traffic;
  cs.collect.seed = derive_seed(d.seed, static_cast<uint64_t>(i));
  cs.collect.episodes = d.episodes;
  cs.collect.out = out;
  cs.collect.noise.enabled = false;
  CollectOptions co;
  co.quiet = quiet;
  co.driver = [policy, settings, beta] {
    return std::make_unique<DaggerDriver>(policy, settings, beta);
  };
  co.policy_checkpoint = policy;
  collect(cs, co);
  Rollouts r;
  for (const std::string& f : list_episode_files(out)) {
    EpisodeMeta m = read_episode_meta(f);
    r.frames += static_cast<long>(read_episode(f, nullptr).frames());
    ++r.outcomes[m.outcome];
  }
  return r;
}

// MuJoCo-Image: episodes of the data's env from dagger.seed (never an eval's initial states),
// at the data's frame size, with the [mujoco] settings' workers, step limit and planner.
Rollouts mujoco_rollouts(const Settings& settings, const std::string& data_dir, int i,
                         const std::string& policy, double beta, const std::string& out,
                         bool quiet) {
  const std::vector<std::string> files = list_episode_files(data_dir);
  if (files.empty()) throw DataError(data_dir + " holds no episode files");
  const MujocoEpisode first = read_mujoco_episode(files.front());
  mj::CollectOptions o;
  o.env = first.env;
  o.out = out;
  o.episodes = settings.dagger.episodes;
  o.seed = derive_seed(settings.dagger.seed, static_cast<uint64_t>(i));
  o.workers = settings.mujoco.workers;
  o.width = first.width;
  o.height = first.height;
  o.max_steps = settings.mujoco.max_steps;
  o.planner = mj::planner_options(settings.mujoco);
  o.expert_policies = mj::expert_policies_for(settings.mujoco.expert_policies, o.env, o.planner);
  o.quiet = quiet;
  const std::string env = first.env;
  o.driver = [policy, env, beta] { return std::make_unique<MujocoDaggerDriver>(policy, env, beta); };
  o.policy_checkpoint = policy;
  o.batch = settings.eval.batch;
  o.device = "cpu";  // MujocoDaggerDriver's FramePolicy runs on the CPU
  mj::collect(o);
  Rollouts r;
  for (const std::string& f : list_episode_files(out)) {
    const MujocoEpisode m = read_mujoco_episode(f);
    r.frames += static_cast<long>(m.frames());
    ++r.outcomes[m.outcome];
  }
  return r;
}

json read_record(const std::string& path) {
  std::error_code ec;
  if (!fs::exists(path, ec)) return json();
  try {
    return json::parse(read_file_bytes(path));
  } catch (const std::exception&) {
    throw DataError(path + " is damaged; delete the folder to start over");
  }
}

void copy_file_atomic(const std::string& from, const std::string& to) {
  write_file_atomic(to, read_file_bytes(from));
}

}  // namespace

double dagger_beta(const DaggerSettings& d, int iteration) {
  return d.beta * std::pow(d.beta_decay, iteration - 1);
}

TrainSummary train_dagger(const Settings& settings, const TrainRequest& req) {
  const DaggerSettings& d = settings.dagger;
  if (req.out_dir.empty()) throw ConfigError("train: no output folder given (--out)");
  const std::string out = req.out_dir;
  refuse_other_method_folder(out, "dagger");
  const std::string record_path = out + "/" + kDaggerJson;
  json record = read_record(record_path);
  const json dagger_settings = settings_to_json(settings)["dagger"];
  if (!record.is_null() && record.value("settings", json()) != dagger_settings)
    throw ConfigError(out + " holds a dagger run with other [dagger] settings; use another --out");
  if (record.is_null())
    record = {{"method", "dagger"},
              {"data", canonical_dir(req.data_dir)},
              {"settings", dagger_settings},
              {"iterations", json::array()},
              {"expert_labels", 0}};
  fs::create_directories(out);

  const FamilyMethod method = bc_family_method();
  TrainRequest r = req;
  r.out_dir = iteration_dir(out, 0);
  if (!req.quiet) log_line("dagger iteration 0: bc-oh on the expert data");
  TrainSummary sum = train_policy_family(settings, r, method, {{req.data_dir}, ""});

  const bool mujoco = data_domain(req.data_dir) == kMujocoDomain;
  std::vector<std::string> dirs = {req.data_dir};
  long labels = 0;
  for (int i = 1; i <= d.iterations; ++i) {
    const double beta = dagger_beta(d, i);
    const std::string policy = iteration_dir(out, i - 1);
    const std::string rollouts = rollout_dir(out, i);
    if (!req.quiet)
      log_line("dagger iteration " + std::to_string(i) + ": " + std::to_string(d.episodes) +
               " closed-loop episodes, expert with probability " + std::to_string(beta));
    const Rollouts done =
        mujoco ? mujoco_rollouts(settings, req.data_dir, i, policy, beta, rollouts, req.quiet)
               : driving_rollouts(settings, i, policy, beta, rollouts, req.quiet);
    dirs.push_back(rollouts);
    const long frames = done.frames;
    labels += frames;

    Settings ts = settings;
    ts.train.epochs = d.epochs;
    r.out_dir = iteration_dir(out, i);
    sum = train_policy_family(ts, r, method, {dirs, policy + "/" + kBestFile});

    json it = {{"iteration", i},       {"beta", beta},
               {"episodes", d.episodes}, {"expert_labels", frames},
               {"outcomes", done.outcomes}, {"rollouts", fs::path(rollouts).filename().string()},
               {"policy", fs::path(r.out_dir).filename().string()}};
    json& its = record["iterations"];
    if (static_cast<int>(its.size()) < i) its.push_back(it);
    record["expert_labels"] = labels;
    write_file_atomic(record_path, record.dump(2) + "\n");
    inject_crash("dagger", i, out, CrashScope::ProcessGroup);
  }

  // The last iteration is the dagger policy: its run, copied to the top of the folder.
  const std::string last = iteration_dir(out, d.iterations);
  Checkpoint ck = require_checkpoint(last);
  ck.method_record = record;
  for (const char* f : {kBestFile, kModelFile}) copy_file_atomic(last + "/" + f, out + "/" + f);
  write_file_atomic(out + "/" + kMetricsJsonl, metrics_jsonl(ck));
  write_file_atomic(out + "/" + kCheckpointJson, checkpoint_to_json(ck).dump(2) + "\n");
  sum.out_dir = out;
  return sum;
}

}  // namespace cd
