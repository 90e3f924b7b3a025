#include "cli/common.hpp"

#include <cstdio>

#include "core/progress.hpp"
#include "runs/checkpoint.hpp"

namespace cd::cli {

void print_train_summary(const TrainSummary& s) {
  std::printf("trained %s in %s: %d epochs", s.method.c_str(), s.out_dir.c_str(), s.epochs_done);
  if (s.resumed_from > 0) std::printf(" (%d were done before this run)", s.resumed_from);
  std::printf("\n  samples: %ld train (%d episodes), %ld validation (%d episodes)\n",
              s.train_samples, s.train_episodes, s.val_samples, s.val_episodes);
  std::printf("  %s %d, %s loss %.5f -> %s/%s\n", s.last_kept ? "kept the last epoch" : "best epoch",
              s.best_epoch,
              s.has_validation ? "validation" : "training", s.best_loss, s.out_dir.c_str(),
              s.weights_file.empty() ? kBestFile : s.weights_file.c_str());
  if (s.samples_per_s > 0)
    std::printf("  time %s on %s, %.0f samples/s\n", format_duration(s.seconds).c_str(),
                s.device.c_str(), s.samples_per_s);
  else
    std::printf("  nothing left to train (%d epochs already done)\n", s.epochs_done);
}

}  // namespace cd::cli
