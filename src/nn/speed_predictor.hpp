#pragma once
// The causal speed predictor of the cim family (seed 000 section 5.4.3): each input variable's
// last `history` values go through its own Linear(history -> units) + ReLU; the V encodings
// are concatenated and an MLP (Linear -> ReLU -> Linear) gives the next speed in m/s.
// The V per-variable encoders are held as one V x history x units weight (a batched matmul),
// which is the same function as V separate Linear layers and fast for cim-mlp's 128.
//
// This header includes torch: include it only from the .cpp files that run the network.
#include <torch/torch.h>

namespace cd {

struct SpeedPredictorOptions {
  int variables = 1;  // V: selected causes (cim, cim-entangled) or all latents (cim-mlp)
  int history = 3;
  int units = 16;     // per-variable encoder width
  int hidden = 64;
};

struct SpeedPredictorImpl : torch::nn::Module {
  explicit SpeedPredictorImpl(const SpeedPredictorOptions& options);

  // x: B x V x history (oldest first) -> B x 1, the next speed (m/s, unclamped).
  torch::Tensor forward(const torch::Tensor& x);

  const SpeedPredictorOptions& options() const { return options_; }

  torch::Tensor enc_weight, enc_bias;  // V x history x units, V x units
  torch::nn::Sequential head{nullptr};

 private:
  SpeedPredictorOptions options_;
};
TORCH_MODULE(SpeedPredictor);

}  // namespace cd
