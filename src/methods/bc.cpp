// bc-so and bc-oh (seed 001's baselines): behaviour cloning of the expert's recorded actions
// from the current frame (bc-so) or a stack of real history frames (bc-oh), resumable.
//
// Loss: L(action) + model.speed_loss_weight * L(speed head), L = L1 or L2 (train.loss); Adam
// with the plateau rule of train/loop.hpp (train.lr_patience, lr_decay, lr_min). The weights
// come from train.seed, shuffling and dropout of epoch n from (seed, n), so a run resumed after
// epoch n gives the same bytes as one that never stopped (with the same train.threads).
// The run folder and its commit protocol are in runs/checkpoint.hpp.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <optional>
#include <sstream>

#include <ATen/Parallel.h>

#include "agents/agent.hpp"
#include "control/pid.hpp"
#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "core/progress.hpp"
#include "datasets/dataset.hpp"
#include "inference/policy_runner.hpp"
#include "methods/method.hpp"
#include "nn/policy_net.hpp"
#include "runs/checkpoint.hpp"
#include "runs/record.hpp"
#include "train/loop.hpp"

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
                              key == "device");
}

torch::Tensor loss_of(const std::string& kind, const torch::Tensor& pred,
                      const torch::Tensor& target) {
  return kind == "l2" ? torch::mse_loss(pred, target) : torch::l1_loss(pred, target);
}

template <class T>
std::string to_bytes(const T& object) {
  torch::serialize::OutputArchive archive;
  object.save(archive);
  std::ostringstream os;
  archive.save_to(os);
  return os.str();
}

// The network, its batches and its loss over the dataset's two splits.
class BcObjective : public Objective {
 public:
  BcObjective(const Dataset& data, PolicyNet& net, const torch::Device& device, const Settings& s)
      : data_(data), net_(net), device_(device), s_(s) {
    const int B = s.train.batch_size;
    auto f = torch::TensorOptions().dtype(torch::kFloat32);
    const EpisodeSet& eps = data.episodes();
    image_ = torch::empty({B, data.input_channels(), eps.height, eps.width}, f);
    speed_in_ = torch::empty({B, 1}, f);
    command_ = torch::empty({B}, torch::TensorOptions().dtype(torch::kInt64));
    action_ = torch::empty({B, data.action_dim()}, f);
    speed_label_ = torch::empty({B, 1}, f);
  }

  void set_training(bool on) override { on ? net_->train() : net_->eval(); }

  BatchLoss loss(bool training, const uint32_t* rows, int64_t n) override {
    const std::vector<SampleRef>& samples = training ? data_.train() : data_.val();
    const size_t iv = data_.image_values();
    float* img = image_.data_ptr<float>();
    float* sp = speed_in_.data_ptr<float>();
    int64_t* cmd = command_.data_ptr<int64_t>();
    float* act = action_.data_ptr<float>();
    float* lab = speed_label_.data_ptr<float>();
    const int A = data_.action_dim();
    // Unpacking the frames is a tenth of a step: spread it over torch's threads too (each
    // sample writes its own rows, so the result does not depend on the thread count).
    at::parallel_for(0, n, 8, [&](int64_t lo, int64_t hi) {
      for (int64_t i = lo; i < hi; ++i)
        data_.fill(samples[rows[i]], {img + i * iv, sp + i, cmd + i, act + i * A, lab + i});
    });
    auto on = [&](const torch::Tensor& t) { return t.narrow(0, 0, n).to(device_); };
    PolicyOutput out = net_->forward(on(image_), on(speed_in_), on(command_), true);
    torch::Tensor total = loss_of(s_.train.loss, out.action, on(action_));
    if (s_.model.speed_loss_weight > 0)
      total = total + s_.model.speed_loss_weight * loss_of(s_.train.loss, out.speed, on(speed_label_));
    return {total, {}};
  }

 private:
  const Dataset& data_;
  PolicyNet& net_;
  torch::Device device_;
  const Settings& s_;
  torch::Tensor image_, speed_in_, command_, action_, speed_label_;
};

// The network and optimiser of the last committed epoch in `out`.
void restore(torch::nn::Module& net, torch::optim::Adam& opt, const std::string& out,
             const torch::Device& device) {
  load_module_bytes(net, read_file_bytes(out + "/" + kModelFile), device, out + "/" + kModelFile);
  try {
    std::istringstream is(read_file_bytes(out + "/" + kOptimizerFile));
    torch::serialize::InputArchive archive;
    archive.load_from(is, device);
    opt.load(archive);
  } catch (const c10::Error&) {
    throw DataError(out + "/" + kOptimizerFile + " does not fit the network; delete the folder "
                    "to start over");
  }
}

void refuse_other_checkpoint(const Checkpoint& c, const std::string& method,
                             const json& settings, const std::string& data_dir,
                             const std::string& out) {
  refuse_other_run({c.method, c.settings, c.data_dir}, {method, settings, data_dir}, out,
                   {"model", "train"}, may_differ);
}

}  // namespace

TrainSummary train_bc(const Settings& settings_in, const TrainRequest& req) {
  const auto run_start = Clock::now();
  const Settings s = effective_settings(req.method, settings_in);
  if (req.out_dir.empty()) throw ConfigError("train: no output folder given (--out)");
  const std::string out = req.out_dir;
  const std::string data_dir = canonical_dir(req.data_dir);
  const json settings_json = settings_to_json(s);

  // A folder that holds another run is refused before any data is read.
  std::optional<Checkpoint> previous = read_checkpoint(out);
  if (previous) refuse_other_checkpoint(*previous, req.method, settings_json, data_dir, out);

  const TrainingDevice dev = training_device(s.train.device, s.train.threads);

  DatasetOptions dopt;
  dopt.history = s.model.history;
  dopt.stride = s.model.history_stride;
  dopt.action_head = s.model.action_head;
  dopt.speed_input = s.model.speed_input;
  dopt.val_fraction = s.train.val_fraction;
  dopt.seed = s.train.seed;
  dopt.max_samples = s.train.max_samples;
  Dataset data(load_episode_set(req.data_dir), dopt);

  Checkpoint ck;
  if (previous) {
    ck = *previous;
    if (ck.train_samples != static_cast<long>(data.train().size()) ||
        ck.val_samples != static_cast<long>(data.val().size()))
      throw ConfigError(out + " holds a checkpoint trained on " +
                        std::to_string(ck.train_samples) + " + " +
                        std::to_string(ck.val_samples) + " samples, but " + data_dir + " now gives " +
                        std::to_string(data.train().size()) + " + " +
                        std::to_string(data.val().size()) +
                        ": the data changed; train into another --out folder");
  } else {
    ck.method = req.method;
    ck.data_dir = data_dir;
    ck.train_samples = static_cast<long>(data.train().size());
    ck.val_samples = static_cast<long>(data.val().size());
    ck.val_episodes = static_cast<int>(data.val_episodes().size());
    ck.train_episodes = static_cast<int>(data.episodes().episodes.size()) - ck.val_episodes;
    ck.lr = s.train.lr;
  }
  const EpisodeSet& eps = data.episodes();
  ck.settings = settings_json;
  ck.model = s.model;
  ck.device = dev.name;
  ck.input = {eps.channels, eps.height, eps.width, s.model.history, s.model.history_stride,
              eps.dt, eps.metres_per_pixel, eps.channel_names};

  fs::create_directories(out);
  settle_pending_files(out, ck.epochs_done);

  TrainSummary sum = train_summary(req, dev.name, ck.train_samples, ck.val_samples,
                                   ck.train_episodes, ck.val_episodes);
  sum.resumed_from = ck.epochs_done;

  torch::manual_seed(s.train.seed);
  PolicyNet net(policy_net_options(s.model, data.input_channels(), eps.height, eps.width));
  net->to(dev.device);
  torch::optim::Adam opt(net->parameters(), torch::optim::AdamOptions(s.train.lr));
  if (ck.epochs_done > 0) {
    restore(*net, opt, out, dev.device);
    if (!req.quiet) log_line("resuming " + out + " after epoch " + std::to_string(ck.epochs_done));
  }

  const int epochs = s.train.epochs;
  const size_t n_train = data.train().size();
  std::optional<Progress> progress;
  if (!req.quiet && ck.epochs_done < epochs)
    progress.emplace("train " + req.method, static_cast<long>(n_train) * epochs,
                     static_cast<long>(n_train) * ck.epochs_done);

  LoopPlan plan;
  plan.first_epoch = ck.epochs_done + 1;
  plan.last_epoch = epochs;
  plan.batch_size = s.train.batch_size;
  plan.train_size = n_train;
  plan.val_size = data.val().size();
  plan.shuffle_seed = s.train.seed ^ kShuffleStream;
  plan.torch_seed = s.train.seed;
  plan.lr_patience = s.train.lr_patience;
  plan.lr_decay = s.train.lr_decay;
  plan.lr_min = s.train.lr_min;
  plan.progress = progress ? &*progress : nullptr;
  plan.note = [epochs](int epoch, double loss) { return epoch_note(epoch, epochs, "loss", loss, 4); };
  LoopState state{ck.best_epoch > 0, ck.best_epoch, ck.best_loss, ck.bad_epochs, ck.lr};

  BcObjective objective(data, net, dev.device, s);
  const LoopTotals totals = train_epochs(objective, opt, plan, state, [&](const EpochResult& r) {
    ck.best_epoch = state.best_epoch;
    ck.best_loss = state.best_loss;
    ck.bad_epochs = state.bad_epochs;
    ck.lr = state.lr;
    // Commit: state files under pending names, then checkpoint.json, then the renames.
    const std::string model_bytes = save_module_bytes(*net);
    write_file_atomic(out + "/" + pending_name(kModelFile, r.epoch), model_bytes);
    if (r.improved) write_file_atomic(out + "/" + pending_name(kBestFile, r.epoch), model_bytes);
    write_file_atomic(out + "/" + pending_name(kOptimizerFile, r.epoch), to_bytes(opt));
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

// A trained network in closed loop: throttle/brake as it outputs them, or its target speed
// tracked by the speed PID of [control].
class BcAgent : public Agent {
 public:
  BcAgent(const std::string& method, const std::string& dir, const Settings& s)
      : method_(method), runner_(dir, method), pid_(s.control, EgoModel(s.ego), s.world.dt) {}

  std::string name() const override { return method_; }
  int history() const override { return runner_.history(); }
  int history_stride() const override { return runner_.stride(); }
  void begin_episode() override {
    pid_.reset();
    target_ = std::nan("");
  }

  Control act(const Observation& obs) override {
    const InputFormat& in = runner_.checkpoint().input;
    check_observation(method_, obs, in.channels, in.height, in.width, in.history);
    PolicyStep step = runner_.run(obs.frames.data(), obs.speed, obs.command);
    if (runner_.target_speed_head()) {
      target_ = step.target_speed;
      return pid_.control(target_, obs.speed);
    }
    return Control{step.throttle, step.brake};
  }

  double last_target_speed() const override { return target_; }

 private:
  std::string method_;
  PolicyRunner runner_;
  SpeedPid pid_;
  double target_ = std::nan("");
};

}  // namespace

std::unique_ptr<Agent> load_bc_agent(const std::string& method, const std::string& dir,
                                     const Settings& settings, const World*) {
  set_torch_threads(1);
  return std::make_unique<BcAgent>(method, dir, settings);
}

void bc_so_settings(Settings& s) {
  s.model.history = 1;
  s.model.history_stride = 1;
}

}  // namespace cd
