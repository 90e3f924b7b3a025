#include "nn/beta_vae.hpp"

#include <algorithm>

#include "core/error.hpp"

namespace cd {

namespace nn = torch::nn;

namespace {
nn::LeakyReLU leaky() { return nn::LeakyReLU(nn::LeakyReLUOptions().negative_slope(0.01)); }
nn::Conv2d conv(int in, int out) {
  return nn::Conv2d(nn::Conv2dOptions(in, out, 4).stride(2).padding(1));
}
nn::ConvTranspose2d deconv(int in, int out) {
  return nn::ConvTranspose2d(nn::ConvTranspose2dOptions(in, out, 4).stride(2).padding(1));
}
}  // namespace

BetaVaeImpl::BetaVaeImpl(int latents) : latents_(latents) {
  if (latents < 1) throw ConfigError("vae.latents must be >= 1");
  enc_convs = register_module(
      "enc_convs", nn::Sequential(conv(1, 32), leaky(), conv(32, 32), leaky(), conv(32, 32),
                                  leaky(), conv(32, 64), leaky()));
  enc_fc = register_module("enc_fc",
                           nn::Sequential(nn::Linear(64 * 4 * 4, 256), leaky(), nn::Linear(256, 256),
                                          leaky(), nn::Linear(256, 2 * latents)));
  dec_fc = register_module("dec_fc",
                           nn::Sequential(nn::Linear(latents, 256), leaky(), nn::Linear(256, 256),
                                          leaky(), nn::Linear(256, 64 * 4 * 4), leaky()));
  dec_convs = register_module(
      "dec_convs", nn::Sequential(deconv(64, 32), leaky(), deconv(32, 32), leaky(),
                                  deconv(32, 32), leaky(), deconv(32, 1)));
}

std::pair<torch::Tensor, torch::Tensor> BetaVaeImpl::encode(const torch::Tensor& x) {
  torch::Tensor h = enc_convs->forward(x).flatten(1);
  torch::Tensor out = enc_fc->forward(h);
  return {out.narrow(1, 0, latents_), out.narrow(1, latents_, latents_)};
}

torch::Tensor BetaVaeImpl::decode(const torch::Tensor& z) {
  torch::Tensor h = dec_fc->forward(z).view({-1, 64, 4, 4});
  return dec_convs->forward(h);
}

VaeOutput BetaVaeImpl::forward(const torch::Tensor& x, bool sample) {
  auto [mu, logvar] = encode(x);
  torch::Tensor z = sample ? mu + torch::exp(0.5 * logvar) * torch::randn_like(mu) : mu;
  return {decode(z), mu, logvar};
}

torch::Tensor kl_per_latent(const torch::Tensor& mu, const torch::Tensor& logvar) {
  // KL(N(mu, sigma^2) || N(0, 1)) = 0.5 * (mu^2 + sigma^2 - 1 - log sigma^2) per latent.
  return 0.5 * (mu.pow(2) + logvar.exp() - 1.0 - logvar);
}

int active_latents(const std::vector<double>& mean_kl) {
  return static_cast<int>(
      std::count_if(mean_kl.begin(), mean_kl.end(), is_active_latent));
}

VaeLoss vae_loss(const torch::Tensor& logits, const torch::Tensor& target, const torch::Tensor& mu,
                 const torch::Tensor& logvar, double beta) {
  const int64_t b = logits.size(0);
  torch::Tensor bce = torch::binary_cross_entropy_with_logits(
      logits.reshape({b, -1}), target.reshape({b, -1}), {}, {}, at::Reduction::None);
  torch::Tensor recon = bce.sum(1).mean();
  torch::Tensor kl = kl_per_latent(mu, logvar).sum(1).mean();
  return {recon + beta * kl, recon, kl};
}

}  // namespace cd
