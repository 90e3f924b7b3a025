// dim and rip (seed 000's baselines): the imitative trajectory density of nn/dim_net.hpp,
// trained by maximum likelihood, one member after the other (rip: dim.ensemble members, each
// on a bootstrap resample of the training episodes); in closed loop, a plan by likelihood
// ascent toward the route goal, driven at the speed it implies.
//
// Samples: every step t of every episode with t + horizon*waypoint_step < T whose future holds
// no noise-injected step (datasets/episode_set.hpp, expert_motion); labels are the
// future positions, inputs frame t and the past positions, all in the ego frame of t
// (datasets/trajectory.hpp). Validation holds out whole episodes (choose_val_episodes);
// train.max_samples keeps a seeded subset of both splits, shrunk by the same fraction.
// Randomness of member k (weights, bootstrap, shuffling of epoch n) comes from (train.seed, k,
// n) only, so a member retrained after an interruption gives the same bytes.
// The run folder is runs/dim_run.hpp.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <deque>
#include <filesystem>
#include <optional>

#include <ATen/Parallel.h>

#include "agents/agent.hpp"
#include "control/pid.hpp"
#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "core/progress.hpp"
#include "core/rng.hpp"
#include "datasets/split.hpp"
#include "datasets/trajectory.hpp"
#include "expert/autopilot.hpp"
#include "inference/dim_planner.hpp"
#include "inference/policy_runner.hpp"
#include "methods/method.hpp"
#include "nn/dim_net.hpp"
#include "runs/dim_run.hpp"
#include "runs/record.hpp"
#include "sense/bev.hpp"
#include "sense/grey_view.hpp"
#include "train/loop.hpp"

namespace cd {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

using Clock = std::chrono::steady_clock;

constexpr uint64_t kSubsetStream = 0x5ab5e7d1;
constexpr uint64_t kBootstrapStream = 0xb0075;
constexpr uint64_t kWeightStream = 0x3e1917;
constexpr uint64_t kShuffleStream = 0x5f1e;

// Keys that may change between runs into the same folder: where the output goes and the
// compute resources (the bytes are the same for the same train.threads).
bool may_differ(const std::string& table, const std::string& key) {
  if (table == "dim")  // the planner's settings: used by the agents only
    return key == "plan_iterations" || key == "plan_lr" || key == "goal_distance" ||
           key == "goal_weight" || key == "goal" || key == "plan_speed" ||
           key == "replan_steps" || key == "aggregation";
  return table == "train" && (key == "out" || key == "threads" || key == "device");
}

struct Samples {
  std::vector<SampleRef> train, val;
  std::vector<int> val_episodes, train_episodes;
};

Samples make_samples(const EpisodeSet& eps, const Settings& s) {
  const DimSettings& d = s.dim;
  const int n = static_cast<int>(eps.episodes.size());
  Samples out;
  out.val_episodes = choose_val_episodes(n, s.train.val_fraction, s.train.seed);
  const int reach = d.horizon * d.waypoint_step;
  for (int e = 0; e < n; ++e) {
    const bool val = std::binary_search(out.val_episodes.begin(), out.val_episodes.end(), e);
    if (!val) out.train_episodes.push_back(e);
    for (int t = 0; t + reach < eps.episodes[e].frames; ++t)
      if (expert_motion(eps.episodes[e], t, t + reach))  // the future is the expert's motion
        (val ? out.val : out.train).push_back({e, t});
  }
  Rng rng(derive_seed(s.train.seed, kSubsetStream));
  cap_splits(out.train, out.val, s.train.max_samples, rng, SubsetDraw::Partial);
  if (out.train.empty())
    throw DataError("data folder '" + eps.dir + "' leaves no dim training sample (episodes " +
                    "need more than dim.horizon * dim.waypoint_step = " + std::to_string(reach) +
                    " steps; " + std::to_string(out.val.size()) + " validation samples)");
  return out;
}

// Member k of rip: as many training episodes drawn with replacement as there are, and the
// (kept) samples of each draw; dim trains on every training sample.
std::vector<SampleRef> member_samples(const Samples& all, const std::string& method,
                                      uint64_t seed, int member, std::vector<int>& draws) {
  draws.clear();
  if (method != "rip") return all.train;
  Rng rng(derive_seed(seed ^ kBootstrapStream, static_cast<uint64_t>(member)));
  const size_t n = all.train_episodes.size();
  std::vector<SampleRef> out;
  for (size_t i = 0; i < n; ++i) {
    const int e = all.train_episodes[rng.below(n)];
    draws.push_back(e);
    // all.train is sorted by episode: its samples of e are one range.
    auto lo = std::lower_bound(all.train.begin(), all.train.end(), e,
                               [](const SampleRef& s, int ep) { return s.episode < ep; });
    for (auto it = lo; it != all.train.end() && it->episode == e; ++it) out.push_back(*it);
  }
  if (out.empty()) return all.train;  // every draw hit an episode without kept samples
  return out;
}

// One member's negative log-likelihood over its samples and the validation samples.
class DimObjective : public Objective {
 public:
  DimObjective(const EpisodeSet& eps, const DimSettings& d, const std::vector<SampleRef>& train,
               const std::vector<SampleRef>& val, DimNet& net, const torch::Device& device,
               int capacity)
      : eps_(eps), d_(d), train_(train), val_(val), net_(net), device_(device),
        keep_(view_channel_flags(d.view, eps.channel_names, "dim.view")) {
    frames_ = torch::empty({capacity, eps.channels, eps.height, eps.width});
    past_ = torch::empty({capacity, d.past, 2});
    future_ = torch::empty({capacity, d.horizon, 2});
  }

  void set_training(bool on) override { on ? net_->train() : net_->eval(); }

  BatchLoss loss(bool training, const uint32_t* rows, int64_t n) override {
    const std::vector<SampleRef>& samples = training ? train_ : val_;
    float* f = frames_.data_ptr<float>();
    float* p = past_.data_ptr<float>();
    float* z = future_.data_ptr<float>();
    const size_t fv = eps_.frame_values();
    // Each sample writes its own rows: the result does not depend on the thread count.
    at::parallel_for(0, n, 8, [&](int64_t lo, int64_t hi) {
      for (int64_t i = lo; i < hi; ++i) {
        const SampleRef& s = samples[rows[i]];
        eps_.planes01(s.episode, s.t, f + i * fv);
        blank_other_channels(keep_, eps_.frame_pixels(), f + i * fv);
        dim_sample_positions(eps_.episodes[s.episode], s.t, d_, p + i * 2 * d_.past,
                             z + i * 2 * d_.horizon);
      }
    });
    auto on = [&](const torch::Tensor& t) { return t.narrow(0, 0, n).to(device_); };
    torch::Tensor features = net_->encode(on(frames_));
    return {-net_->log_prob(features, on(past_), on(future_)).mean(), {}};
  }

 private:
  const EpisodeSet& eps_;
  const DimSettings& d_;
  const std::vector<SampleRef>& train_;
  const std::vector<SampleRef>& val_;
  DimNet& net_;
  torch::Device device_;
  std::vector<bool> keep_;  // dim.view: the channels the model sees
  torch::Tensor frames_, past_, future_;
};

// Trains member m of the run on its samples (weights from (train.seed, m)); returns its best
// weights, fills its metrics and best epoch.
std::string train_member(DimMember& m, const std::vector<SampleRef>& train, const Samples& samples,
                         const EpisodeSet& eps, const Settings& s, const std::string& method,
                         const ComputeDevice& dev, Progress* progress, bool quiet,
                         LoopTotals& totals) {
  const DimSettings& d = s.dim;
  const int epochs = s.train.epochs;
  const DimNetOptions no = dim_net_options(d, eps.channels, eps.height, eps.width);
  m.train_samples = static_cast<long>(train.size());
  m.metrics.clear();
  const uint64_t member_seed = derive_seed(s.train.seed, static_cast<uint64_t>(m.index));

  torch::manual_seed(derive_seed(member_seed, kWeightStream));
  DimNet net(no);
  net->to(dev.device);
  torch::optim::Adam opt(net->parameters(), torch::optim::AdamOptions(s.train.lr));
  std::string best_bytes;

  LoopPlan plan;
  plan.last_epoch = epochs;
  plan.batch_size = s.train.batch_size;
  plan.train_size = train.size();
  plan.epoch_samples = static_cast<size_t>(s.train.epoch_samples);
  plan.val_size = samples.val.size();
  plan.shuffle_seed = member_seed ^ kShuffleStream;
  // The NLL of a badly placed sample can be huge while sigma is small: bound the step.
  plan.clip_grad_norm = 10.0;
  plan.stop_patience = d.patience;  // any better validation NLL restarts the count
  plan.device = &dev;
  plan.progress = progress;
  const std::string member = "member " + std::to_string(m.index + 1) + "/" +
                             std::to_string(d.ensemble) + " ";
  plan.note = [&](int epoch, double v) { return member + epoch_note(epoch, epochs, "nll", v, 3); };
  LoopState state;
  state.lr = s.train.lr;

  DimObjective objective(eps, d, train, samples.val, net, dev.device, s.train.batch_size);
  const LoopTotals t = train_epochs(objective, opt, plan, state, [&](const EpochResult& r) {
    DimEpochMetrics em;
    static_cast<EpochMetrics&>(em) = r.metrics();
    em.member = m.index;
    m.metrics.push_back(em);
    if (r.improved) {
      net->to(torch::kCPU);
      best_bytes = save_module_bytes(*net);
      net->to(dev.device);
    }
    char line[200];
    std::snprintf(line, sizeof line,
                  "%s member %d/%d epoch %d/%d: train nll %.4f, val nll %s, %.0f samples/s",
                  method.c_str(), m.index + 1, d.ensemble, r.epoch, epochs, em.train_loss,
                  r.val_loss ? std::to_string(*r.val_loss).c_str() : "-", em.samples_per_s);
    if (!quiet) log_line(line);
  });
  m.best_epoch = state.best_epoch;
  m.best_nll = state.best_loss;
  totals.samples += t.samples;
  totals.seconds += t.seconds;
  return best_bytes;
}

}  // namespace

TrainSummary train_dim(const Settings& settings_in, const TrainRequest& req) {
  const auto run_start = Clock::now();
  const Settings s = effective_settings(req.method, settings_in);
  if (req.out_dir.empty()) throw ConfigError("train: no output folder given (--out)");
  const std::string out = req.out_dir;
  const std::string data_dir = canonical_dir(req.data_dir);
  const json settings_json = settings_to_json(s);
  const DimSettings& d = s.dim;

  // A folder that holds another run is refused before any data is read.
  refuse_other_method_folder(out, req.method);
  std::optional<DimRun> previous = read_dim_run(out);
  if (previous)
    refuse_other_run({previous->method, previous->settings, previous->data_dir},
                     {req.method, settings_json, data_dir}, out, {"dim", "train"}, may_differ);

  const ComputeDevice dev = training_device(s.train);

  const EpisodeSet eps = load_episode_set(req.data_dir);
  for (const auto& e : eps.episodes)
    if (e.pose.size() != 3 * static_cast<size_t>(e.frames))
      throw DataError(req.data_dir + "/" + e.file + " has no pose (T x 3) series: dim needs it");
  view_channel_flags(s.dim.view, eps.channel_names, "dim.view");  // a bad view: one line, now
  const Samples samples = make_samples(eps, s);

  DimRun run;
  if (previous) {
    run = *previous;
    if (run.train_samples != static_cast<long>(samples.train.size()) ||
        run.val_samples != static_cast<long>(samples.val.size()) ||
        run.input.channels != eps.channels || run.input.height != eps.height ||
        run.input.width != eps.width)
      throw ConfigError(out + " holds a run trained on other data than " + data_dir +
                        " now gives: the data changed; train into another --out folder");
  } else {
    run.method = req.method;
    run.settings = settings_json;
    run.dim = d;
    run.input = {eps.channels, eps.height, eps.width, 1, 1, eps.action_dim, eps.dt, eps.metres_per_pixel,
                 eps.channel_names, eps.domain, eps.env, ""};  // no action squash: dim plans
    run.data_dir = data_dir;
    run.train_samples = static_cast<long>(samples.train.size());
    run.val_samples = static_cast<long>(samples.val.size());
    run.train_episodes = static_cast<int>(samples.train_episodes.size());
    run.val_episodes = static_cast<int>(samples.val_episodes.size());
    for (int k = 0; k < d.ensemble; ++k) {
      DimMember m;
      m.index = k;
      run.members.push_back(m);
    }
  }
  run.device = dev.name;
  run.runtime = dev.record();

  TrainSummary sum = train_summary(req, dev.name, run.train_samples, run.val_samples,
                                   run.train_episodes, run.val_episodes);
  sum.weights_file = run.members.size() > 1 ? "member_*.pt" : dim_member_file(0);
  for (const DimMember& m : run.members)
    if (m.finished) sum.resumed_from += static_cast<int>(m.metrics.size());

  fs::create_directories(out);
  remove_stale_temporaries(out);
  write_file_atomic(out + "/" + kDimJson, dim_run_to_json(run).dump(2) + "\n");

  const int epochs = s.train.epochs;
  long to_train = 0;
  std::vector<std::vector<SampleRef>> member_train(run.members.size());
  for (DimMember& m : run.members) {
    if (m.finished) continue;
    member_train[m.index] =
        member_samples(samples, req.method, s.train.seed, m.index, m.episodes);
    to_train += static_cast<long>(epoch_size(member_train[m.index].size(),
                                             static_cast<size_t>(s.train.epoch_samples))) * epochs;
  }
  std::optional<Progress> progress;
  if (!req.quiet && to_train > 0) progress.emplace("train " + req.method, to_train);
  LoopTotals totals;

  for (DimMember& m : run.members) {
    if (m.finished) continue;
    const std::string best_bytes =
        train_member(m, member_train[m.index], samples, eps, s, req.method, dev,
                     progress ? &*progress : nullptr, req.quiet, totals);
    // Commit the member: its weights, then the record that says it is finished.
    write_file_atomic(out + "/" + dim_member_file(m.index), best_bytes);
    m.finished = true;
    write_file_atomic(out + "/" + kDimJson, dim_run_to_json(run).dump(2) + "\n");
    write_file_atomic(out + "/" + kMetricsJsonl, dim_metrics_jsonl(run));
  }
  if (progress) progress->finish();
  // Regenerated also when nothing was left to train.
  write_file_atomic(out + "/" + kMetricsJsonl, dim_metrics_jsonl(run));

  for (const DimMember& m : run.members) sum.epochs_done += static_cast<int>(m.metrics.size());
  sum.best_epoch = run.members.front().best_epoch;
  sum.best_loss = run.members.front().best_nll;
  sum.seconds = std::chrono::duration<double>(Clock::now() - run_start).count();
  sum.samples_per_s = totals.samples_per_s();
  return sum;
}

// ---- the agent ------------------------------------------------------------------------------

namespace {

struct OdoPose {
  double x, y, heading;
};

// Every dim.replan_steps steps, plan a trajectory by maximising the (aggregated) likelihood of
// the run's members plus the goal term, and drive at the speed the plan implies with the
// shared speed PID. With ego.lateral = "route" the ego follows its route lanes exactly, so the
// plan's speed is all that reaches the vehicle; with "free" the plan is also the path it steers
// along (pure pursuit on the planned waypoints, kept in the network frame between replans).
// The measured speed is not an input (POMDP): the model sees the current frame and the past
// positions from odometry.
class DimAgent : public Agent {
 public:
  DimAgent(const std::string& method, const std::string& dir, const Settings& s)
      : method_(method),
        planner_(dir, method),
        pid_(s.control, EgoModel(s.ego), s.world.dt),
        planning_(s.dim),
        ego_(s.ego) {
    planner_.set_planning(planning_);
    // Frames of another view or size are refused by make_agent (require_trained_view).
  }

  std::string name() const override { return method_; }
  int history() const override { return 1; }
  // Planning settings come from the evaluation's config ([dim] plan_*, goal_*, replan_steps,
  // aggregation), the network's from the run.
  double goal_distance() const override { return planning_.goal_distance; }
  bool steers() const override { return true; }  // along its plan (ego.lateral = "free")

  void begin_episode() override {
    pid_.reset();
    poses_.clear();
    steps_ = 0;
    target_ = std::nan("");
    plans_ = moved_plans_ = 0;
    gain_sum_ = moved_sum_ = 0;
    plan_.clear();
  }

  Control act(const Observation& obs) override {
    const InputFormat& in = planner_.run().input;
    check_observation(method_, obs, in.channels, in.height, in.width, 1);
    const DimSettings& d = planner_.run().dim;
    // Odometry of every step, newest last; before the first act() the ego stood still, so a
    // position older than what was seen is the first one seen.
    const size_t keep = static_cast<size_t>(d.past) * d.waypoint_step + 1;
    poses_.push_back({obs.x, obs.y, obs.heading});
    if (poses_.size() > keep) poses_.pop_front();
    const OdoPose& now = poses_.back();
    std::vector<double> past(2 * d.past);
    for (int k = 0; k < d.past; ++k) {
      const long back = static_cast<long>(k + 1) * d.waypoint_step;
      const long i = std::max(0L, static_cast<long>(poses_.size()) - 1 - back);
      const Vec2 e = to_ego_frame(Pose2{{now.x, now.y}, now.heading}, Vec2{poses_[i].x, poses_[i].y});
      past[2 * k] = e.x;
      past[2 * k + 1] = e.y;
    }
    // Replanning every replan_steps steps (the plan covers horizon * waypoint_step steps); the
    // speed of the last plan is tracked in between.
    if (steps_++ % planning_.replan_steps == 0) {
      const DimStep step = planner_.plan(obs.frames.back(), past, obs.goal_x, obs.goal_y);
      target_ = step.target_speed;
      // The plan in the network frame, from where the ego stands now.
      const double c = std::cos(now.heading), sn = std::sin(now.heading);
      plan_.assign(1, Vec2{now.x, now.y});
      for (size_t k = 0; k + 1 < step.plan.size(); k += 2)
        plan_.push_back({now.x + c * step.plan[k] - sn * step.plan[k + 1],
                         now.y + sn * step.plan[k] + c * step.plan[k + 1]});
      ++plans_;
      gain_sum_ += step.objective_after - step.objective_before;
      moved_sum_ += step.moved_m;
      moved_plans_ += step.objective_after > step.objective_before;
    }
    Control control = pid_.control(target_, obs.speed);
    if (ego_.lateral == "free" && plan_.size() > 1) {
      // Pure pursuit towards the plan point a speed-dependent distance ahead of the front
      // bumper, measured along the plan from the ego's projection onto it.
      const Pose2 pose{{now.x, now.y}, now.heading};
      const double ahead = std::clamp(1.0 + 0.3 * target_, 1.5, 8.0) + 0.5 * ego_.length;
      control.steer = pursuit_steer(pose, point_along_polyline(plan_, pose.pos, ahead), ego_);
    }
    return control;
  }

  double last_target_speed() const override { return target_; }

  // How far the likelihood ascent moves the plan in closed loop (issue: does the planner
  // plan, or is the plan the model's mean rollout?).
  nlohmann::json episode_figures() const override {
    const double n = plans_ > 0 ? static_cast<double>(plans_) : 1.0;
    return {{"plans", plans_},
            {"plan_objective_gain", gain_sum_ / n},
            {"plans_improved", moved_plans_ / n},
            {"plan_moved_m", moved_sum_ / n}};
  }

 private:
  std::string method_;
  DimPlanner planner_;
  SpeedPid pid_;
  DimSettings planning_;
  EgoSettings ego_;
  std::vector<Vec2> plan_;  // the last plan's waypoints, network frame, from the ego's position
  std::deque<OdoPose> poses_;
  long steps_ = 0;
  double target_ = std::nan("");
  long plans_ = 0, moved_plans_ = 0;  // this episode's plans, those the ascent improved
  double gain_sum_ = 0, moved_sum_ = 0;  // J(plan) - J(initial guess); metres moved
};

}  // namespace

std::unique_ptr<Agent> load_dim_agent(const std::string& method, const std::string& dir,
                                      const Settings& settings, const World*) {
  set_torch_threads(1);
  return std::make_unique<DimAgent>(method, dir, settings);
}

void dim_single_model(Settings& s) { s.dim.ensemble = 1; }

}  // namespace cd
