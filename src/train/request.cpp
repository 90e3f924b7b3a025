#include "train/request.hpp"

#include "core/error.hpp"

namespace cd {

TrainSummary train_summary(const TrainRequest& request, const std::string& device,
                           long train_samples, long val_samples, int train_episodes,
                           int val_episodes) {
  TrainSummary s;
  s.method = request.method;
  s.out_dir = request.out_dir;
  s.device = device;
  s.train_samples = train_samples;
  s.val_samples = val_samples;
  s.train_episodes = train_episodes;
  s.val_episodes = val_episodes;
  s.has_validation = val_samples > 0;
  return s;
}

}  // namespace cd
