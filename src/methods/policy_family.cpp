#include "methods/policy_family.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <optional>
#include <sstream>

#include <ATen/Parallel.h>

#include "agents/agent.hpp"
#include "control/pid.hpp"
#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "core/progress.hpp"
#include "datasets/situation.hpp"
#include "inference/policy_runner.hpp"
#include "methods/method.hpp"
#include "runs/checkpoint.hpp"
#include "runs/record.hpp"

namespace cd {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

using Clock = std::chrono::steady_clock;

constexpr uint64_t kShuffleStream = 0x7a11;

// Keys that may change between runs into the same folder: the number of epochs (to train
// further), where the output goes, and the compute resources.
bool may_differ(const std::string& table, const std::string& key) {
  return table == "train" && (key == "epochs" || key == "out" || key == "threads" ||
                              key == "device" || key == "cuda_deterministic");
}

// The networks and optimiser of the last committed epoch in `out`.
void restore(PolicyNets& nets, torch::optim::Adam& opt, const std::string& out,
             const torch::Device& device) {
  nets.load_bytes(read_file_bytes(out + "/" + kModelFile), device, out + "/" + kModelFile);
  load_optimizer_bytes(opt, read_file_bytes(out + "/" + kOptimizerFile), device,
                       out + "/" + kOptimizerFile, "; delete the folder to start over");
}

std::string join_dirs(const std::vector<std::string>& dirs) {
  std::string s;
  for (const auto& d : dirs) s += (s.empty() ? "" : " + ") + d;
  return s;
}

}  // namespace

// ---- batches and losses ---------------------------------------------------------------------

torch::Tensor PolicyBatch::current(int frame_channels) const {
  return image.narrow(1, image.size(1) - frame_channels, frame_channels);
}

PolicyBatcher::PolicyBatcher(const Dataset& data, int B, const torch::Device& device,
                             const std::vector<float>& train_weights)
    : data_(data), device_(device), cuda_(device.is_cuda()) {
  if (!train_weights.empty())
    train_weights_ = torch::tensor(train_weights, torch::kFloat32).to(device);
  auto f = torch::TensorOptions().dtype(torch::kFloat32).pinned_memory(cuda_);
  auto i64 = torch::TensorOptions().dtype(torch::kInt64).pinned_memory(cuda_);
  const EpisodeSet& eps = data.episodes();
  const int A = data.action_dim(), L = data.options().action_lags;
  for (int k = 0; k < (cuda_ ? 2 : 1); ++k) {
    Staging& s = staging_[k];
    s.image = torch::empty({B, data.input_channels(), eps.height, eps.width}, f);
    s.speed_in = torch::empty({B, 1}, f);
    s.command = torch::empty({B}, i64);
    s.action = torch::empty({B, A}, f);
    s.speed_label = torch::empty({B, 1}, f);
    if (L > 0) s.previous = torch::empty({B, L, A}, f);
    s.rows = torch::empty({B}, i64);
  }
}

PolicyBatch PolicyBatcher::batch(bool training, const uint32_t* rows, int64_t n) {
  const std::vector<SampleRef>& samples = training ? data_.train() : data_.val();
  const size_t iv = data_.image_values();
  const int A = data_.action_dim(), L = data_.options().action_lags;
  const Staging& st = staging_[next_];
  if (cuda_) next_ ^= 1;
  float* img = st.image.data_ptr<float>();
  float* sp = st.speed_in.data_ptr<float>();
  int64_t* cmd = st.command.data_ptr<int64_t>();
  float* act = st.action.data_ptr<float>();
  float* lab = st.speed_label.data_ptr<float>();
  float* prev = L > 0 ? st.previous.data_ptr<float>() : nullptr;
  int64_t* r = st.rows.data_ptr<int64_t>();
  at::parallel_for(0, n, 8, [&](int64_t lo, int64_t hi) {
    for (int64_t i = lo; i < hi; ++i) {
      data_.fill(samples[rows[i]], {img + i * iv, sp + i, cmd + i, act + i * A, lab + i,
                                    prev ? prev + i * L * A : nullptr});
      r[i] = rows[i];
    }
  });
  auto on = [&](const torch::Tensor& t) {
    return t.narrow(0, 0, n).to(device_, /*non_blocking=*/cuda_);
  };
  PolicyBatch b;
  b.n = n;
  b.image = on(st.image);
  b.speed_in = on(st.speed_in);
  b.command = on(st.command);
  b.action = on(st.action);
  b.speed_label = on(st.speed_label);
  if (L > 0) b.previous = on(st.previous);
  b.rows = on(st.rows);
  if (training && train_weights_.defined()) b.weight = train_weights_.index_select(0, b.rows);
  return b;
}

torch::Tensor sample_weights(const PolicyBatch& batch, const torch::Tensor& own) {
  if (!batch.weight.defined()) return own;
  if (!own.defined()) return batch.weight;
  return own.dim() == 2 ? own * batch.weight.unsqueeze(1) : own * batch.weight;
}

Settings resolve_recipe(Settings s, const std::string& domain, bool situation_causes) {
  const bool driving = domain == kDrivingDomain;
  if (s.model.pedals == "auto")
    s.model.pedals = driving && s.model.action_head == "throttle_brake" ? "signed" : "two";
  if (s.train.situation_weights == "auto")
    s.train.situation_weights = driving && situation_causes ? "balanced" : "none";
  return s;
}

namespace {
// resolve_recipe for the data folder `dir` (its domain and, for driving, its first episode's
// causes), before the rest of the data is read.
Settings resolve_recipe_for(const Settings& s, const std::string& dir) {
  const std::string domain = data_domain(dir);
  const bool causes = domain == kDrivingDomain && s.train.situation_weights == "auto" &&
                      records_situation_causes(dir);
  return resolve_recipe(s, domain, causes);
}
}  // namespace

std::vector<float> situation_weights(const Settings& settings, const Dataset& data) {
  const EpisodeSet& eps = data.episodes();
  const bool causes = !eps.episodes.empty() && has_situation_causes(eps.episodes.front().causes);
  const Settings s = resolve_recipe(settings, eps.domain, causes);
  if (s.train.situation_weights == "none") return {};
  if (eps.domain != kDrivingDomain)
    throw ConfigError("train.situation_weights = \"" + s.train.situation_weights +
                      "\" needs driving data; " + eps.dir + " holds " + eps.domain + " data");
  std::vector<int> classes;
  classes.reserve(data.train().size());
  try {
    for (const SampleRef& r : data.train())
      classes.push_back(situation_class(situations_at(eps.episodes[r.episode], r.t, eps.dt)));
  } catch (const DataError& e) {
    throw ConfigError(std::string("train.situation_weights = \"balanced\": ") + e.what() +
                      " (train with train.situation_weights = \"none\")");
  }
  return balanced_weights(classes, s.train.situation_weight_max);
}

torch::Tensor action_loss(const std::string& kind, const torch::Tensor& pred,
                          const torch::Tensor& target, const torch::Tensor& weights) {
  if (!weights.defined())
    return kind == "l2" ? torch::mse_loss(pred, target) : torch::l1_loss(pred, target);
  const torch::Tensor d = pred - target;
  const torch::Tensor per = (kind == "l2" ? d * d : d.abs());
  if (weights.dim() == 2) return (per * weights).mean();  // per sample and component
  return (per.mean(1) * weights).mean();
}

torch::Tensor policy_loss(const Settings& s, const PolicyOutput& out, const torch::Tensor& target,
                          const torch::Tensor& speed_label, const torch::Tensor& weights) {
  torch::Tensor total = action_loss(s.train.loss, out.action, target, weights);
  if (s.model.speed_loss_weight > 0)
    total = total + s.model.speed_loss_weight * action_loss(s.train.loss, out.speed, speed_label);
  return total;
}

PolicyNetsLayout layout_for(const std::string& method, const Settings& s, const EpisodeSet& eps) {
  return policy_layout(method, s.model, s.residual, s.fca, eps.channels, eps.height, eps.width,
                       eps.action_dim, eps.domain);
}

// ---- the trainer ----------------------------------------------------------------------------

TrainSummary train_policy_family(const Settings& settings_in, const TrainRequest& req,
                                 const FamilyMethod& method, const FamilyData& data_in) {
  const auto run_start = Clock::now();
  if (req.out_dir.empty()) throw ConfigError("train: no output folder given (--out)");
  const std::string out = req.out_dir;
  const std::vector<std::string> dirs =
      data_in.dirs.empty() ? std::vector<std::string>{req.data_dir} : data_in.dirs;
  const Settings s = resolve_recipe_for(effective_settings(req.method, settings_in), dirs.front());
  std::vector<std::string> canonical;
  for (const auto& d : dirs) canonical.push_back(canonical_dir(d));
  const std::string data_dir = join_dirs(canonical);
  const json settings_json = settings_to_json(s);

  std::vector<std::string> tables = {"model", "train"};
  tables.insert(tables.end(), method.tables.begin(), method.tables.end());
  // A folder that holds another run is refused before any data is read.
  std::optional<Checkpoint> previous = read_checkpoint(out);
  if (previous)
    refuse_other_run({previous->method, previous->settings, previous->data_dir},
                     {req.method, settings_json, data_dir}, out, tables, may_differ);

  const ComputeDevice dev = training_device(s.train);

  DatasetOptions dopt;
  dopt.history = s.model.history;
  dopt.stride = s.model.history_stride;
  dopt.action_head = s.model.action_head;
  dopt.speed_input = s.model.speed_input;
  dopt.val_fraction = s.train.val_fraction;
  dopt.seed = s.train.seed;
  dopt.max_samples = s.train.max_samples;
  dopt.action_lags = method.action_lags(s);
  dopt.signed_pedals = s.model.pedals == "signed" && s.model.action_head == "throttle_brake";
  Dataset data(load_episode_set(dirs), dopt);
  const EpisodeSet& eps = data.episodes();
  const PolicyNetsLayout layout = layout_for(req.method, s, eps);

  Checkpoint ck;
  if (previous) {
    ck = *previous;
    if (ck.train_samples != static_cast<long>(data.train().size()) ||
        ck.val_samples != static_cast<long>(data.val().size()))
      throw ConfigError(out + " holds a checkpoint trained on " +
                        std::to_string(ck.train_samples) + " + " +
                        std::to_string(ck.val_samples) + " samples, but " + data_dir +
                        " now gives " + std::to_string(data.train().size()) + " + " +
                        std::to_string(data.val().size()) +
                        ": the data changed; train into another --out folder");
  } else {
    ck.method = req.method;
    ck.data_dir = data_dir;
    ck.train_samples = static_cast<long>(data.train().size());
    ck.val_samples = static_cast<long>(data.val().size());
    ck.val_episodes = static_cast<int>(data.val_episodes().size());
    for (int e : data.val_episodes()) ck.val_files.push_back(eps.episodes[e].file);
    ck.train_episodes = static_cast<int>(eps.episodes.size()) - ck.val_episodes;
    ck.lr = s.train.lr;
  }
  ck.settings = settings_json;
  ck.model = s.model;
  ck.residual = s.residual;
  ck.fca = s.fca;
  ck.device = dev.name;
  ck.runtime = dev.record();
  ck.input = {eps.channels,       eps.height, eps.width, s.model.history, s.model.history_stride,
              eps.action_dim,     eps.dt,     eps.metres_per_pixel, eps.channel_names,
              eps.domain,         eps.env,    ""};
  // Recorded where the squash is not driving's (throttle, brake) sigmoid (InputFormat).
  if (layout.action_output != "sigmoid") ck.input.action_output = layout.action_output;

  fs::create_directories(out);
  settle_pending_files(out, ck.epochs_done);

  TrainSummary sum = train_summary(req, dev.name, ck.train_samples, ck.val_samples,
                                   ck.train_episodes, ck.val_episodes);
  sum.resumed_from = ck.epochs_done;

  torch::manual_seed(s.train.seed);
  PolicyNets nets(layout);
  nets.to(dev.device);
  torch::optim::AdamOptions adam =
      method.adam ? method.adam(s) : torch::optim::AdamOptions(s.train.lr);
  adam.weight_decay(s.train.weight_decay);
  torch::optim::Adam opt(nets.parameters(), adam);
  if (ck.epochs_done > 0) {
    restore(nets, opt, out, dev.device);
    if (!req.quiet) log_line("resuming " + out + " after epoch " + std::to_string(ck.epochs_done));
  } else if (!data_in.init_weights.empty()) {
    nets.load_bytes(read_file_bytes(data_in.init_weights), dev.device, data_in.init_weights);
  }

  const int epochs = s.train.epochs;
  PolicyBatcher batcher(data, s.train.batch_size, dev.device, situation_weights(s, data));
  FamilyContext ctx{s, data, nets, batcher, dev.device, req.quiet};
  json record = ck.method_record;
  std::unique_ptr<Objective> objective = method.objective(ctx, record);
  ck.method_record = record;

  LoopPlan plan;
  plan.first_epoch = ck.epochs_done + 1;
  plan.last_epoch = epochs;
  plan.batch_size = s.train.batch_size;
  plan.train_size = data.train().size();
  plan.epoch_samples = static_cast<size_t>(s.train.epoch_samples);
  const long per_epoch = static_cast<long>(epoch_size(plan));
  std::optional<Progress> progress;
  if (!req.quiet && ck.epochs_done < epochs)
    progress.emplace("train " + req.method, per_epoch * epochs, per_epoch * ck.epochs_done);

  plan.val_size = data.val().size();
  plan.shuffle_seed = s.train.seed ^ kShuffleStream;
  plan.torch_seed = s.train.seed;
  plan.lr_patience = s.train.lr_patience;
  plan.lr_decay = s.train.lr_decay;
  plan.lr_min = s.train.lr_min;
  plan.device = &dev;
  plan.progress = progress ? &*progress : nullptr;
  plan.note = [epochs](int epoch, double loss) { return epoch_note(epoch, epochs, "loss", loss, 4); };
  LoopState state{ck.best_epoch > 0, ck.best_epoch, ck.best_loss, ck.bad_epochs, ck.lr};

  const LoopTotals totals = train_epochs(*objective, opt, plan, state, [&](const EpochResult& r) {
    ck.best_epoch = state.best_epoch;
    ck.best_loss = state.best_loss;
    ck.bad_epochs = state.bad_epochs;
    ck.lr = state.lr;
    // Commit: state files under pending names, then checkpoint.json, then the renames.
    const std::string model_bytes = nets.save_bytes();
    write_file_atomic(out + "/" + pending_name(kModelFile, r.epoch), model_bytes);
    if (r.improved) write_file_atomic(out + "/" + pending_name(kBestFile, r.epoch), model_bytes);
    write_file_atomic(out + "/" + pending_name(kOptimizerFile, r.epoch), save_optimizer_bytes(opt));
    ck.metrics.push_back(r.metrics());
    ck.epochs_done = r.epoch;
    write_file_atomic(out + "/" + kCheckpointJson, checkpoint_to_json(ck).dump(2) + "\n");
    settle_pending_files(out, r.epoch);
    write_file_atomic(out + "/" + kMetricsJsonl, metrics_jsonl(ck));
  });
  if (progress) progress->finish();
  // Regenerated also when nothing was left to train (a run killed after its last commit).
  write_file_atomic(out + "/" + kMetricsJsonl, metrics_jsonl(ck));

  sum.epochs_done = ck.epochs_done;
  sum.best_epoch = ck.best_epoch;
  sum.best_loss = ck.best_loss;
  sum.seconds = std::chrono::duration<double>(Clock::now() - run_start).count();
  sum.samples_per_s = totals.samples_per_s();
  return sum;
}

// ---- the agent ------------------------------------------------------------------------------

namespace {

// A trained family policy in closed loop: the action as its networks output it, or its target
// speed tracked by the speed PID of [control]. It remembers the action it executed last (what
// residual's memory-only controller adds its residual to); before its first act() the ego
// stood braked (the runner's history prefill).
class FamilyAgent : public Agent {
 public:
  FamilyAgent(const std::string& method, const std::string& dir, const Settings& s)
      : method_(method),
        runner_(dir, method, kBestFile, s.eval.device),
        pid_(s.control, EgoModel(s.ego), s.world.dt) {
    const InputFormat& in = runner_.checkpoint().input;
    if (in.domain != "driving")
      throw ConfigError("checkpoint " + dir + " was trained on MuJoCo-Image data ('" + in.env +
                        "'): evaluate it with `causaldrive eval --env " + in.env + "`");
    steers_ = in.action_dim >= 3 && !runner_.target_speed_head();
    if (s.ego.lateral == "free" && !steers_)
      throw ConfigError("checkpoint " + dir + " was trained without steer (" +
                        (runner_.target_speed_head() ? std::string("a target-speed head")
                                                     : std::string("throttle and brake")) +
                        "): it cannot drive with ego.lateral = \"free\"; use \"route\" or train "
                        "on data collected with ego.lateral = \"free\"");
  }

  std::string name() const override { return method_; }
  int history() const override { return runner_.history(); }
  int history_stride() const override { return runner_.stride(); }
  void begin_episode() override {
    pid_.reset();
    target_ = std::nan("");
    previous_ = Control{0.0, 1.0};
  }

  Control act(const Observation& obs) override {
    const InputFormat& in = runner_.checkpoint().input;
    check_observation(method_, obs, in.channels, in.height, in.width, in.history);
    const float prev[3] = {static_cast<float>(previous_.throttle),
                           static_cast<float>(previous_.brake),
                           static_cast<float>(previous_.steer)};
    PolicyStep step = runner_.run(obs.frames.data(), obs.speed, obs.command, prev);
    if (runner_.target_speed_head()) {
      target_ = step.target_speed;
      previous_ = pid_.control(target_, obs.speed);
    } else {
      previous_ = Control{step.throttle, step.brake, steers_ ? step.steer : 0.0};
    }
    return previous_;
  }

  double last_target_speed() const override { return target_; }
  bool steers() const override { return steers_; }

 private:
  std::string method_;
  PolicyRunner runner_;
  SpeedPid pid_;
  double target_ = std::nan("");
  Control previous_{0.0, 1.0};
  bool steers_ = false;  // trained on (throttle, brake, steer): data of a free-steering ego
};

}  // namespace

std::unique_ptr<Agent> load_policy_family_agent(const std::string& method, const std::string& dir,
                                                const Settings& settings, const World*) {
  set_torch_threads(1);
  return std::make_unique<FamilyAgent>(method, dir, settings);
}

}  // namespace cd
