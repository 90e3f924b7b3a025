#pragma once
// The perception model of the cim family (seed 000 section 5.4.2): a beta-VAE on one 64x64
// grey view of the BEV.
//
//   encoder: 4 convolutions (32, 32, 32, 64 filters; k4 s2 p1: 64 -> 32 -> 16 -> 8 -> 4 px)
//            -> FC 256 -> FC 256 -> FC 2*latents (mu, logvar)
//   decoder: FC 256 -> FC 256 -> FC 64*4*4 -> 4 transposed convolutions (32, 32, 32, 1;
//            k4 s2 p1: 4 -> 8 -> 16 -> 32 -> 64 px) -> logits of Bernoulli pixels
// LeakyReLU (slope 0.01) after every layer except the encoder's last FC and the decoder's
// output. Loss per image: BCE with logits summed over the pixels + beta * KL(q(z|x) || N(0,I))
// summed over the latents; the batch loss is the mean over images.
//
// This header includes torch: include it only from the .cpp files that run the network.
#include <vector>

#include <torch/torch.h>

namespace cd {

inline constexpr int kVaeSize = 64;  // input and output are 1 x 64 x 64

struct VaeOutput {
  torch::Tensor logits;  // B x 1 x 64 x 64
  torch::Tensor mu, logvar;  // B x latents
};

struct VaeLoss {
  torch::Tensor loss;   // mean over the batch of recon + beta * kl
  torch::Tensor recon;  // mean over the batch of the per-image BCE (summed over pixels)
  torch::Tensor kl;     // mean over the batch of the per-image KL (summed over latents)
};

struct BetaVaeImpl : torch::nn::Module {
  explicit BetaVaeImpl(int latents);

  // x: B x 1 x 64 x 64 in [0, 1]. Returns (mu, logvar), each B x latents.
  std::pair<torch::Tensor, torch::Tensor> encode(const torch::Tensor& x);
  // z: B x latents -> logits B x 1 x 64 x 64 (sigmoid gives the pixel probabilities).
  torch::Tensor decode(const torch::Tensor& z);
  // sample: z = mu + exp(logvar / 2) * eps (training); otherwise z = mu (deterministic).
  VaeOutput forward(const torch::Tensor& x, bool sample = true);

  int latents() const { return latents_; }

  torch::nn::Sequential enc_convs{nullptr}, enc_fc{nullptr};
  torch::nn::Sequential dec_fc{nullptr}, dec_convs{nullptr};

 private:
  int latents_;
};
TORCH_MODULE(BetaVae);

// KL(N(mu, sigma^2) || N(0, 1)) of each latent of each image: B x latents.
torch::Tensor kl_per_latent(const torch::Tensor& mu, const torch::Tensor& logvar);

// A latent is active when its KL, averaged over the data, exceeds this many nats: the others
// carry (almost) no information about the image (the usual count for posterior collapse).
inline constexpr double kActiveKlNats = 0.01;
inline bool is_active_latent(double mean_kl) { return mean_kl > kActiveKlNats; }
// How many of the latents' mean KLs exceed kActiveKlNats.
int active_latents(const std::vector<double>& mean_kl);

// The loss above for logits/targets of B x 1 x 64 x 64 (targets in [0, 1]).
VaeLoss vae_loss(const torch::Tensor& logits, const torch::Tensor& target, const torch::Tensor& mu,
                 const torch::Tensor& logvar, double beta);

}  // namespace cd
