#include "learn/trainer.hpp"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <sstream>

#include <ATen/Parallel.h>

#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "core/progress.hpp"
#include "core/rng.hpp"
#include "learn/checkpoint.hpp"
#include "learn/dataset.hpp"
#include "learn/methods.hpp"
#include "nn/policy_net.hpp"

namespace cd {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

using Clock = std::chrono::steady_clock;

// Keys that may change between runs into the same folder: the number of epochs (to train
// further), where the output goes, and the compute resources.
bool may_differ(const std::string& table, const std::string& key) {
  return table == "train" && (key == "epochs" || key == "out" || key == "threads" ||
                              key == "device");
}

void check_resumable(const Checkpoint& c, const std::string& method, const json& settings,
                     const std::string& data_dir, const std::string& out_dir) {
  const std::string where = out_dir + "/" + kCheckpointJson;
  if (c.method != method)
    throw ConfigError(out_dir + " holds a checkpoint of method '" + c.method +
                      "', not '" + method + "': train into another --out folder");
  std::string diff = settings_diff(c.settings, settings, {"model", "train"}, may_differ);
  if (!diff.empty())
    throw ConfigError(out_dir + " holds a checkpoint trained with other settings (" + diff +
                      "): train into another --out folder, or delete it to start over");
  if (c.data_dir != data_dir)
    throw ConfigError(out_dir + " holds a checkpoint trained on " + c.data_dir + ", not " +
                      data_dir + ": train into another --out folder");
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

void set_lr(torch::optim::Adam& opt, double lr) {
  for (auto& group : opt.param_groups())
    static_cast<torch::optim::AdamOptions&>(group.options()).lr(lr);
}

// One batch in host memory, filled sample by sample, then moved to the device.
struct Batch {
  torch::Tensor image, speed_in, command, action, speed_label;

  Batch(const Dataset& d, int capacity) {
    auto f = torch::TensorOptions().dtype(torch::kFloat32);
    image = torch::empty({capacity, d.input_channels(), d.episodes().height, d.episodes().width}, f);
    speed_in = torch::empty({capacity, 1}, f);
    command = torch::empty({capacity}, torch::TensorOptions().dtype(torch::kInt64));
    action = torch::empty({capacity, d.action_dim()}, f);
    speed_label = torch::empty({capacity, 1}, f);
  }

  // Fills rows [0, n) from samples[begin, begin + n) (through `order` when given).
  int64_t fill(const Dataset& d, const std::vector<SampleRef>& samples,
               const std::vector<uint32_t>* order, size_t begin, int64_t n) {
    const size_t iv = d.image_values();
    float* img = image.data_ptr<float>();
    float* sp = speed_in.data_ptr<float>();
    int64_t* cmd = command.data_ptr<int64_t>();
    float* act = action.data_ptr<float>();
    float* lab = speed_label.data_ptr<float>();
    const int A = d.action_dim();
    // Unpacking the frames is a tenth of a step: spread it over torch's threads too (each
    // sample writes its own rows, so the result does not depend on the thread count).
    at::parallel_for(0, n, 8, [&](int64_t lo, int64_t hi) {
      for (int64_t i = lo; i < hi; ++i) {
        size_t k = begin + static_cast<size_t>(i);
        const SampleRef& s = samples[order ? (*order)[k] : k];
        d.fill(s, {img + i * iv, sp + i, cmd + i, act + i * A, lab + i});
      }
    });
    return n;
  }
};

torch::Tensor batch_loss(PolicyNet& net, const Batch& b, int64_t n, const torch::Device& device,
                  const Settings& s) {
  auto on = [&](const torch::Tensor& t) { return t.narrow(0, 0, n).to(device); };
  PolicyOutput out = net->forward(on(b.image), on(b.speed_in), on(b.command), true);
  torch::Tensor total = loss_of(s.train.loss, out.action, on(b.action));
  if (s.model.speed_loss_weight > 0)
    total = total + s.model.speed_loss_weight * loss_of(s.train.loss, out.speed, on(b.speed_label));
  return total;
}

void print_line(bool quiet, const std::string& line) {
  if (quiet) return;
  std::fprintf(stderr, "%s\n", line.c_str());
  std::fflush(stderr);
}

}  // namespace

std::string resolve_device(const std::string& wanted) {
  if (wanted == "cpu") return "cpu";
  bool cuda = torch::cuda::is_available();
  if (wanted == "auto") return cuda ? "cuda" : "cpu";
  if (wanted == "cuda") {
    if (!cuda)
      throw ConfigError("train.device = \"cuda\" but no CUDA device is usable (this libtorch "
                        "build or machine has none); use \"cpu\" or \"auto\"");
    return "cuda";
  }
  throw ConfigError("train.device must be cpu, cuda or auto (got '" + wanted + "')");
}

TrainSummary train_policy(const Settings& settings_in, const TrainRequest& req) {
  const auto run_start = Clock::now();
  check_train_method(req.method);
  const Settings s = effective_settings(req.method, settings_in);
  if (req.out_dir.empty()) throw ConfigError("train: no output folder given (--out)");
  const std::string out = req.out_dir;
  const std::string data_dir = canonical_dir(req.data_dir);
  const json settings_json = settings_to_json(s);

  // A folder that holds another run is refused before any data is read.
  std::optional<Checkpoint> previous = read_checkpoint(out);
  if (previous) check_resumable(*previous, req.method, settings_json, data_dir, out);

  const std::string device_name = resolve_device(s.train.device);
  const torch::Device device(device_name == "cuda" ? torch::kCUDA : torch::kCPU);
  torch::set_num_threads(s.train.threads);

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
  ck.device = device_name;
  ck.input = {eps.channels, eps.height, eps.width, s.model.history, s.model.history_stride,
              eps.dt, eps.metres_per_pixel, eps.channel_names};

  fs::create_directories(out);
  settle_pending_files(out, ck.epochs_done);

  TrainSummary sum;
  sum.method = req.method;
  sum.out_dir = out;
  sum.device = device_name;
  sum.resumed_from = ck.epochs_done;
  sum.train_samples = ck.train_samples;
  sum.val_samples = ck.val_samples;
  sum.train_episodes = ck.train_episodes;
  sum.val_episodes = ck.val_episodes;
  sum.has_validation = ck.val_samples > 0;

  torch::manual_seed(s.train.seed);
  PolicyNetOptions nopt;
  nopt.in_channels = data.input_channels();
  nopt.height = eps.height;
  nopt.width = eps.width;
  nopt.backbone = s.model.backbone;
  nopt.action_head = s.model.action_head;
  nopt.features = s.model.features;
  nopt.dropout = s.model.dropout;
  PolicyNet net(nopt);
  net->to(device);
  torch::optim::Adam opt(net->parameters(), torch::optim::AdamOptions(s.train.lr));
  if (ck.epochs_done > 0) {
    load_module_bytes(*net, read_file_bytes(out + "/" + kModelFile), device, out + "/" + kModelFile);
    try {
      std::istringstream is(read_file_bytes(out + "/" + kOptimizerFile));
      torch::serialize::InputArchive archive;
      archive.load_from(is, device);
      opt.load(archive);
    } catch (const c10::Error&) {
      throw DataError(out + "/" + kOptimizerFile + " does not fit the network; delete the folder "
                      "to start over");
    }
    print_line(req.quiet, "resuming " + out + " after epoch " + std::to_string(ck.epochs_done));
  }
  set_lr(opt, ck.lr);

  const int epochs = s.train.epochs;
  const int B = s.train.batch_size;
  const size_t n_train = data.train().size(), n_val = data.val().size();
  Batch batch(data, B);
  std::optional<Progress> progress;
  if (!req.quiet && ck.epochs_done < epochs)
    progress.emplace("train " + req.method, static_cast<long>(n_train) * epochs,
                     static_cast<long>(n_train) * ck.epochs_done);
  long trained_now = 0;
  double train_seconds_now = 0;

  for (int epoch = ck.epochs_done + 1; epoch <= epochs; ++epoch) {
    const auto epoch_start = Clock::now();
    torch::manual_seed(derive_seed(s.train.seed, static_cast<uint64_t>(epoch)));
    Rng rng(derive_seed(s.train.seed ^ 0x7a11u, static_cast<uint64_t>(epoch)));
    std::vector<uint32_t> order(n_train);
    for (size_t i = 0; i < n_train; ++i) order[i] = static_cast<uint32_t>(i);
    for (size_t i = n_train; i > 1; --i) std::swap(order[i - 1], order[rng.below(i)]);

    net->train();
    double loss_sum = 0;
    for (size_t begin = 0; begin < n_train; begin += B) {
      int64_t n = std::min<int64_t>(B, static_cast<int64_t>(n_train - begin));
      batch.fill(data, data.train(), &order, begin, n);
      torch::Tensor loss = batch_loss(net, batch, n, device, s);
      opt.zero_grad();
      loss.backward();
      opt.step();
      double v = loss.item<double>();
      loss_sum += v * static_cast<double>(n);
      if (progress) {
        char note[96];
        std::snprintf(note, sizeof note, "epoch %d/%d loss %.4f", epoch, epochs, v);
        progress->advance(n, note);
      }
    }
    const double train_s = std::chrono::duration<double>(Clock::now() - epoch_start).count();

    std::optional<double> val_loss;
    if (n_val > 0) {
      torch::NoGradGuard no_grad;
      net->eval();
      double sum = 0;
      for (size_t begin = 0; begin < n_val; begin += B) {
        int64_t n = std::min<int64_t>(B, static_cast<int64_t>(n_val - begin));
        batch.fill(data, data.val(), nullptr, begin, n);
        sum += batch_loss(net, batch, n, device, s).item<double>() * static_cast<double>(n);
      }
      val_loss = sum / static_cast<double>(n_val);
    }

    EpochMetrics m;
    m.epoch = epoch;
    m.train_loss = loss_sum / static_cast<double>(n_train);
    m.val_loss = val_loss;
    m.lr = ck.lr;
    m.samples_per_s = train_s > 0 ? static_cast<double>(n_train) / train_s : 0.0;
    trained_now += static_cast<long>(n_train);
    train_seconds_now += train_s;

    // Model selection and the plateau schedule follow the validation loss when there is one.
    const double selection = val_loss.value_or(m.train_loss);
    const bool improved = ck.best_epoch == 0 || selection < ck.best_loss;
    if (improved) {
      ck.best_epoch = epoch;
      ck.best_loss = selection;
      ck.bad_epochs = 0;
    } else if (++ck.bad_epochs > s.train.lr_patience) {
      ck.lr = std::max(ck.lr * s.train.lr_decay, s.train.lr_min);
      ck.bad_epochs = 0;
      set_lr(opt, ck.lr);
    }

    // Commit: state files under pending names, then checkpoint.json, then the renames.
    const std::string model_bytes = save_module_bytes(*net);
    write_file_atomic(out + "/" + pending_name(kModelFile, epoch), model_bytes);
    if (improved) write_file_atomic(out + "/" + pending_name(kBestFile, epoch), model_bytes);
    write_file_atomic(out + "/" + pending_name(kOptimizerFile, epoch), to_bytes(opt));
    m.seconds = std::chrono::duration<double>(Clock::now() - epoch_start).count();
    ck.metrics.push_back(m);
    ck.epochs_done = epoch;
    write_file_atomic(out + "/" + kCheckpointJson, checkpoint_to_json(ck).dump(2) + "\n");
    settle_pending_files(out, epoch);
    write_file_atomic(out + "/" + kMetricsJsonl, metrics_jsonl(ck));
  }
  if (progress) progress->finish();
  // Regenerated also when nothing was left to train (a run killed after its last commit).
  write_file_atomic(out + "/" + kMetricsJsonl, metrics_jsonl(ck));

  sum.epochs_done = ck.epochs_done;
  sum.best_epoch = ck.best_epoch;
  sum.best_loss = ck.best_loss;
  sum.seconds = std::chrono::duration<double>(Clock::now() - run_start).count();
  sum.samples_per_s = train_seconds_now > 0 ? trained_now / train_seconds_now : 0.0;
  return sum;
}

}  // namespace cd
