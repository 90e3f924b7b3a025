#pragma once
// Behaviour cloning (bc-so, bc-oh) of the expert's recorded actions, resumable.
//
// Loss: L(action) + model.speed_loss_weight * L(speed head), L = L1 or L2 (train.loss); Adam;
// the learning rate is multiplied by train.lr_decay (never below train.lr_min) when the
// validation loss has not improved for more than train.lr_patience epochs (the rule of
// PyTorch's ReduceLROnPlateau). Every random draw comes from train.seed: the weights from the
// seed, shuffling and dropout of epoch n from (seed, n), so a run resumed after epoch n gives
// the same bytes as one that never stopped (with the same train.threads).
// The folder layout and its commit protocol are in learn/checkpoint.hpp.
#include <optional>
#include <string>

#include "app/settings.hpp"

namespace cd {

struct TrainRequest {
  std::string method;    // a trainable method of learn/methods.hpp
  std::string data_dir;  // a `causaldrive collect` folder
  std::string out_dir;   // checkpoint folder (created; resumed when it holds one)
  bool quiet = false;    // no progress output
  std::string init;      // cim family: fine-tune the speed predictor of this finished run
  std::string vae_from;  // cim family: reuse the VAE of this run instead of training one
};

struct TrainSummary {
  std::string method, out_dir, device;
  int epochs_done = 0;       // in the folder, after this run
  int resumed_from = 0;      // epochs already done when this run started
  int best_epoch = 0;
  double best_loss = 0;      // validation loss of best_epoch (training loss without validation)
  bool has_validation = false;
  long train_samples = 0, val_samples = 0;
  int train_episodes = 0, val_episodes = 0;
  double seconds = 0;        // of this run
  double samples_per_s = 0;  // training throughput of this run (0 when nothing was trained)
  std::string weights_file;  // what agents load, inside out_dir (empty: best.pt)
};

// Trains settings.train.epochs epochs in total (resuming what the folder holds). Throws
// ConfigError for an unavailable method, a folder holding another method's checkpoint or one
// trained with incompatible settings or data; DataError for a missing or damaged data folder.
TrainSummary train_policy(const Settings& settings, const TrainRequest& request);

// The device train.device names: "cpu", or "cuda" (ConfigError when none is usable).
std::string resolve_device(const std::string& wanted);

}  // namespace cd
