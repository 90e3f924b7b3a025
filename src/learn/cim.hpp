#pragma once
// The cim family of seed 000 (cim, cim-mlp, cim-entangled): beta-VAE perception -> Granger cause
// selection -> causal speed predictor. The path is the route the ego follows (README).
#include "learn/trainer.hpp"

namespace cd {

// Trains (or resumes) a cim-family run folder; request.init names a finished run whose VAE and
// causes are reused and whose speed predictor is fine-tuned (few-shot adaptation);
// request.vae_from names a run whose VAE is reused (cim and cim-mlp share one).
TrainSummary train_cim(const Settings& settings, const TrainRequest& request);

}  // namespace cd
