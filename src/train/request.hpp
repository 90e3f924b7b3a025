#pragma once
// What `causaldrive train` is asked (TrainRequest) and what it reports (TrainSummary), the same
// for every method; the methods themselves are in methods/.
#include <string>

#include "app/settings.hpp"

namespace cd {

struct TrainRequest {
  std::string method;    // a trainable method of methods/method.hpp
  std::string data_dir;  // a `causaldrive collect` folder
  std::string out_dir;   // run folder (created; resumed when it holds a run)
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
  bool last_kept = false;    // the weights kept are the last epoch's (few-shot), not the best's
  bool has_validation = false;
  long train_samples = 0, val_samples = 0;
  int train_episodes = 0, val_episodes = 0;
  double seconds = 0;        // of this run
  double samples_per_s = 0;  // training throughput of this run (0 when nothing was trained)
  std::string weights_file;  // what agents load, inside out_dir (empty: best.pt)
};

// A summary's head: the request's method and folder, the device, the split sizes (has_validation
// follows val_samples).
TrainSummary train_summary(const TrainRequest& request, const std::string& device,
                           long train_samples, long val_samples, int train_episodes,
                           int val_episodes);

}  // namespace cd
