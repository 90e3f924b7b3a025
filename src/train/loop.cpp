#include "train/loop.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "core/error.hpp"
#include "core/fault.hpp"
#include "core/progress.hpp"
#include "core/rng.hpp"
#include "app/settings.hpp"

namespace cd {

namespace {

using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point t) {
  return std::chrono::duration<double>(Clock::now() - t).count();
}

void set_flush_denormals(bool on) {
  if (!at::globalContext().setFlushDenormal(on) && on)
    throw ConfigError("train.flush_denormals: this CPU cannot flush denormal floats to zero");
  // Each thread has its own float control register: one OpenMP region as wide as torch's team
  // runs the setting on every one of its threads (libtorch's intra-op threads and OpenBLAS's are
  // libgomp's team of this thread). This file is the one compiled with OpenMP (CMakeLists.txt):
  // ATen's at::parallel_for, a header template, is serial in code built without it.
  const int n = at::get_num_threads();
#pragma omp parallel num_threads(n)
  at::globalContext().setFlushDenormal(on);
}

}  // namespace

double EpochResult::seconds_since_start() const { return seconds_since(started); }

EpochMetrics EpochResult::metrics() const {
  EpochMetrics m;
  m.epoch = epoch;
  m.train_loss = train_loss;
  m.val_loss = val_loss;
  m.lr = lr;
  m.samples_per_s = samples_per_s;
  m.seconds = seconds_since_start();
  return m;
}

BatchLoss Objective::update(const uint32_t* rows, int64_t n, torch::optim::Optimizer& opt,
                            double clip_grad_norm) {
  BatchLoss b = loss(true, rows, n);
  opt.zero_grad();
  b.loss.backward();
  if (clip_grad_norm > 0) {
    std::vector<torch::Tensor> params;
    for (const auto& group : opt.param_groups())
      params.insert(params.end(), group.params().begin(), group.params().end());
    torch::nn::utils::clip_grad_norm_(params, clip_grad_norm);
  }
  opt.step();
  return b;
}

std::string epoch_note(int epoch, int epochs, const char* what, double value, int digits) {
  char note[96];
  std::snprintf(note, sizeof note, "epoch %d/%d %s %.*f", epoch, epochs, what, digits, value);
  return note;
}

ComputeDevice training_device(const TrainSettings& train) {
  ComputeDevice d =
      compute_device(train.device, train.precision, train.cuda_deterministic, train.threads);
  torch::set_num_threads(train.threads);
  set_flush_denormals(train.flush_denormals);
  return d;
}

void set_learning_rate(torch::optim::Optimizer& opt, double lr) {
  for (auto& group : opt.param_groups()) group.options().set_lr(lr);
}

size_t epoch_size(size_t train_size, size_t epoch_samples) {
  return epoch_samples > 0 ? epoch_samples : train_size;
}

size_t epoch_size(const LoopPlan& plan) { return epoch_size(plan.train_size, plan.epoch_samples); }

std::vector<uint32_t> epoch_order(const LoopPlan& plan, int epoch) {
  const uint64_t seed = derive_seed(plan.shuffle_seed, static_cast<uint64_t>(epoch));
  std::vector<uint32_t> order = shuffled_order(plan.train_size, seed);
  const size_t want = plan.train_size == 0 ? 0 : epoch_size(plan);
  for (uint64_t pass = 1; order.size() < want; ++pass) {
    const std::vector<uint32_t> more = shuffled_order(plan.train_size, derive_seed(seed, pass));
    order.insert(order.end(), more.begin(), more.end());
  }
  order.resize(want);
  return order;
}

double validation_loss(Objective& objective, size_t val_size, int batch_size,
                       const ComputeDevice* device) {
  torch::NoGradGuard no_grad;
  const ComputeDevice cpu;
  AutocastScope autocast(device ? *device : cpu);
  objective.set_training(false);
  std::vector<uint32_t> rows(std::min<size_t>(val_size, static_cast<size_t>(batch_size)));
  double sum = 0;
  for (size_t begin = 0; begin < val_size; begin += static_cast<size_t>(batch_size)) {
    const int64_t n = std::min<int64_t>(batch_size, static_cast<int64_t>(val_size - begin));
    for (int64_t i = 0; i < n; ++i) rows[i] = static_cast<uint32_t>(begin + i);
    sum += objective.loss(false, rows.data(), n).loss.item<double>() * static_cast<double>(n);
  }
  return sum / static_cast<double>(val_size);
}

LoopTotals train_epochs(Objective& objective, torch::optim::Optimizer& opt, const LoopPlan& plan,
                        LoopState& state,
                        const std::function<void(const EpochResult&)>& after_epoch) {
  LoopTotals totals;
  const ComputeDevice cpu;
  const ComputeDevice& dev = plan.device ? *plan.device : cpu;
  const bool per_batch = plan.loss_reads == LoopPlan::LossReads::Batch ||
                         (plan.loss_reads == LoopPlan::LossReads::Auto && dev.name != "cuda");
  set_learning_rate(opt, state.lr);
  const size_t B = static_cast<size_t>(plan.batch_size);
  for (int epoch = plan.first_epoch; epoch <= plan.last_epoch; ++epoch) {
    EpochResult r;
    r.epoch = epoch;
    r.lr = state.lr;
    r.started = Clock::now();
    if (plan.torch_seed)
      torch::manual_seed(derive_seed(*plan.torch_seed, static_cast<uint64_t>(epoch)));
    const std::vector<uint32_t> order = epoch_order(plan, epoch);
    const size_t n_train = order.size();

    objective.set_training(true);
    double loss_sum = 0;
    // Per batch: each loss read and counted at once. Per epoch: n x loss summed in float64 where
    // the loss lives (the same products and order as per batch), read once at the end.
    torch::Tensor loss_acc;
    std::vector<torch::Tensor> parts_acc;
    double shown = 0;  // the loss the progress note shows
    Clock::time_point last_read{};
    for (size_t begin = 0; begin < n_train; begin += B) {
      const int64_t n = std::min<int64_t>(plan.batch_size, static_cast<int64_t>(n_train - begin));
      BatchLoss b;
      {
        AutocastScope autocast(dev);
        b = objective.update(order.data() + begin, n, opt, plan.clip_grad_norm);
      }
      const double w = static_cast<double>(n);
      r.train_parts.resize(b.parts.size(), 0.0);
      if (per_batch) {
        shown = b.loss.item<double>();
        ++r.loss_reads;
        loss_sum += shown * w;
        for (size_t k = 0; k < b.parts.size(); ++k)
          r.train_parts[k] += b.parts[k].item<double>() * w;
      } else {
        auto weighted = [&](const torch::Tensor& t) { return t.detach().to(torch::kFloat64) * w; };
        loss_acc = loss_acc.defined() ? loss_acc + weighted(b.loss) : weighted(b.loss);
        parts_acc.resize(b.parts.size());
        for (size_t k = 0; k < b.parts.size(); ++k)
          parts_acc[k] = parts_acc[k].defined() ? parts_acc[k] + weighted(b.parts[k])
                                                : weighted(b.parts[k]);
        if (plan.progress && seconds_since(last_read) >= 1.0) {
          shown = b.loss.item<double>();
          ++r.loss_reads;
          last_read = Clock::now();
        }
      }
      if (plan.progress) plan.progress->advance(n, plan.note ? plan.note(epoch, shown) : "");
    }
    if (loss_acc.defined()) {
      loss_sum = loss_acc.item<double>();
      ++r.loss_reads;
      for (size_t k = 0; k < parts_acc.size(); ++k) r.train_parts[k] = parts_acc[k].item<double>();
    }
    r.train_seconds = seconds_since(r.started);
    r.train_loss = loss_sum / static_cast<double>(n_train);
    for (double& p : r.train_parts) p /= static_cast<double>(n_train);
    r.samples_per_s = r.train_seconds > 0 ? static_cast<double>(n_train) / r.train_seconds : 0.0;
    totals.samples += static_cast<long>(n_train);
    totals.seconds += r.train_seconds;

    if (plan.val_size > 0)
      r.val_loss = validation_loss(objective, plan.val_size, plan.batch_size, &dev);

    // Model selection and the plateau rule follow the validation loss when there is one.
    const double selection = r.selection();
    r.improved = !state.has_best || selection < state.best_loss;
    if (r.improved) {
      state.has_best = true;
      state.best_epoch = epoch;
      state.best_loss = selection;
      state.bad_epochs = 0;
    } else if (plan.lr_patience >= 0 && ++state.bad_epochs > plan.lr_patience) {
      state.lr = std::max(state.lr * plan.lr_decay, plan.lr_min);
      state.bad_epochs = 0;
      set_learning_rate(opt, state.lr);
    }
    bool stop = false;
    if (plan.stop_patience > 0) {
      if (!state.has_stop_ref ||
          selection < state.stop_ref - plan.stop_min_improvement * std::abs(state.stop_ref)) {
        state.has_stop_ref = true;
        state.stop_ref = selection;
        state.stall_epochs = 0;
      } else {
        stop = ++state.stall_epochs >= plan.stop_patience;
      }
    }
    totals.last_epoch = epoch;
    after_epoch(r);
    // CAUSALDRIVE_INJECT_CRASH=train:<epoch> (core/fault.hpp): killed with the epoch committed.
    inject_crash("train", epoch, "");
    if (stop && epoch < plan.last_epoch) {
      totals.stopped_early = true;
      break;
    }
  }
  return totals;
}

}  // namespace cd
