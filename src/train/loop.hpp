#pragma once
// The one epoch loop of every trainer: the seeded shuffle of each epoch, batches, the optimiser
// step, validation, the best-epoch and plateau rules, and progress. A method supplies the loss
// of a batch of its samples (Objective); what it keeps after an epoch (its commit) is its own.
//
// Randomness: epoch n visits the training samples in the order shuffled_order(n_train,
// derive_seed(shuffle_seed, n)) (core/rng.hpp), and, when torch_seed is set, reseeds torch with
// derive_seed(*torch_seed, n) first (dropout, sampling noise). Nothing else draws, so an epoch
// resumed after an interruption gives the same bytes as one that never stopped.
#include <chrono>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include <torch/torch.h>

#include "runs/record.hpp"
#include "device/device.hpp"

namespace cd {

class Progress;
struct TrainSettings;

// A batch's loss (what is minimised) and the parts a method reports beside it (vae: recon, kl).
struct BatchLoss {
  torch::Tensor loss;
  std::vector<torch::Tensor> parts;
};

// What a method trains.
class Objective {
 public:
  virtual ~Objective() = default;
  // The loss of samples rows[0..n) of the training split (training: graph kept, modules in
  // train mode) or of the validation split (rows in order, under NoGradGuard, eval mode).
  virtual BatchLoss loss(bool training, const uint32_t* rows, int64_t n) = 0;
  // Puts the modules in train or eval mode.
  virtual void set_training(bool on) = 0;
  // One optimiser update on this batch: zero_grad, backward, clip, step. Methods with more
  // than one optimiser or alternating steps (seed 001) override it.
  virtual BatchLoss update(const uint32_t* rows, int64_t n, torch::optim::Optimizer& opt,
                           double clip_grad_norm);
};

struct LoopPlan {
  int first_epoch = 1, last_epoch = 1;  // epochs trained now, 1-based, inclusive
  int batch_size = 64;
  size_t train_size = 0, val_size = 0;  // samples of each split
  size_t epoch_samples = 0;  // samples per epoch (epoch_order); 0: train_size
  uint64_t shuffle_seed = 0;
  std::optional<uint64_t> torch_seed;
  double clip_grad_norm = 0;  // > 0: bound the gradient's norm before each step
  // The rule of PyTorch's ReduceLROnPlateau on the selection loss: after more than
  // lr_patience epochs without a better one, lr = max(lr * lr_decay, lr_min). < 0: constant lr.
  int lr_patience = -1;
  double lr_decay = 1, lr_min = 0;
  // Early stop: training ends after stop_patience epochs in a row whose selection loss is not
  // below the reference by more than stop_min_improvement x |reference| (the reference is the
  // loss of the last epoch that was). <= 0: every epoch up to last_epoch is trained.
  int stop_patience = 0;
  double stop_min_improvement = 0;
  // Where the objective's tensors live: its precision (bf16 autocast) applies to every batch
  // (nullptr: the CPU, float32).
  const ComputeDevice* device = nullptr;
  // When a batch's loss is read to the host, which on CUDA waits for every queued step:
  // Batch: after each batch (the CPU, where a read costs nothing). Epoch: the losses are summed
  // where they are and the sum is read once, at the epoch's end, plus at most one read a second
  // for the progress note; nothing else waits for the GPU, so the CPU fills batch n+1 while the
  // GPU runs batch n. Auto: Epoch on CUDA, Batch elsewhere. Both give the same mean.
  enum class LossReads { Auto, Batch, Epoch };
  LossReads loss_reads = LossReads::Auto;
  Progress* progress = nullptr;                            // advanced batch by batch
  std::function<std::string(int epoch, double loss)> note;  // its note after a batch
};

// Carried from epoch to epoch (and across a resume, when the method records it).
struct LoopState {
  bool has_best = false;
  int best_epoch = 0;
  double best_loss = 0;  // selection loss of best_epoch
  int bad_epochs = 0;    // epochs since the last improvement (plateau rule)
  double lr = 0;         // learning rate of the next epoch
  bool has_stop_ref = false;
  double stop_ref = 0;   // selection loss of the last clear improvement (early stop)
  int stall_epochs = 0;  // epochs since then
};

struct EpochResult {
  int epoch = 0;
  double train_loss = 0;            // mean over the epoch's samples
  std::vector<double> train_parts;  // mean of each BatchLoss part
  std::optional<double> val_loss;   // none without validation samples
  double lr = 0;                    // the learning rate the epoch trained with
  double train_seconds = 0;         // of the training pass
  double samples_per_s = 0;         // of the training pass
  bool improved = false;            // this epoch is the new best (state.best_epoch)
  int loss_reads = 0;               // reads of a training loss to the host (syncs on CUDA)
  std::chrono::steady_clock::time_point started;
  double selection() const { return val_loss.value_or(train_loss); }
  double seconds_since_start() const;
  // What run records keep of it; seconds counts from its start to now (the commit included).
  EpochMetrics metrics() const;
};

struct LoopTotals {
  long samples = 0;     // trained in this call
  double seconds = 0;   // of the training passes
  int last_epoch = 0;   // the last epoch trained
  bool stopped_early = false;  // the early-stop rule ended training before plan.last_epoch
  double samples_per_s() const { return seconds > 0 ? samples / seconds : 0.0; }
};

// The training rows epoch `epoch` visits, in order: shuffled_order(train_size, seed of the
// epoch), then (epoch_samples > train_size) further shuffled passes of their own seeds, cut at
// epoch_samples. With epoch_samples 0 or train_size, exactly one pass.
std::vector<uint32_t> epoch_order(const LoopPlan& plan, int epoch);
size_t epoch_size(const LoopPlan& plan);  // epoch_samples, or train_size when 0
size_t epoch_size(size_t train_size, size_t epoch_samples);  // the same rule, before a plan

// The mean loss of the validation split (eval mode, no gradient), in batches in order.
double validation_loss(Objective& objective, size_t val_size, int batch_size,
                       const ComputeDevice* device = nullptr);

// Trains epochs plan.first_epoch..plan.last_epoch (fewer when the early-stop rule ends it); after each, `after_epoch` sees its result
// (the method writes what it keeps). The optimiser's learning rate is set to state.lr first.
LoopTotals train_epochs(Objective& objective, torch::optim::Optimizer& opt, const LoopPlan& plan,
                        LoopState& state,
                        const std::function<void(const EpochResult&)>& after_epoch);

// Sets every parameter group's learning rate (Adam or SGD options).
void set_learning_rate(torch::optim::Optimizer& opt, double lr);

// "epoch 3/8 loss 0.1234": the progress note of a batch (`digits` after the point).
std::string epoch_note(int epoch, int epochs, const char* what, double value, int digits);

// Where a run trains: train.device, train.precision and train.cuda_deterministic resolved
// (device/device.hpp), torch's threads set to train.threads, and denormal floats flushed to zero
// or kept (train.flush_denormals) on this thread and on every one of torch's intra-op threads
// (threads they start later inherit it; a ConfigError where the CPU cannot flush them).
ComputeDevice training_device(const TrainSettings& train);

}  // namespace cd
