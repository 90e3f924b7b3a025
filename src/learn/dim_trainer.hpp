#pragma once
// The imitative trajectory model of seed 000's baselines: dim (one autoregressive Gaussian
// trajectory density) and rip (an ensemble of DIMs trained on bootstrap resamples).
#include "learn/trainer.hpp"

namespace cd {

TrainSummary train_dim(const Settings& settings, const TrainRequest& request);

}  // namespace cd
