// The cim family's networks: beta-VAE shapes, its loss against a hand computation, the
// encoder's determinism; the speed predictor's shapes and per-variable encoders.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>

#include <torch/torch.h>

#include "nn/beta_vae.hpp"
#include "nn/speed_predictor.hpp"

namespace cd {
namespace {

struct OneThread {
  OneThread() { torch::set_num_threads(1); }
};

TEST(BetaVae, ShapesFollowThePaper) {
  OneThread one;
  torch::manual_seed(0);
  BetaVae vae(128);
  torch::Tensor x = torch::rand({3, 1, 64, 64});
  VaeOutput o = vae->forward(x, true);
  EXPECT_EQ(o.mu.sizes(), (std::vector<int64_t>{3, 128}));
  EXPECT_EQ(o.logvar.sizes(), (std::vector<int64_t>{3, 128}));
  EXPECT_EQ(o.logits.sizes(), (std::vector<int64_t>{3, 1, 64, 64}));
  // 4 convolutions 32-32-32-64 (k4) and 3 FC layers of the encoder; the decoder mirrors it.
  int n_conv = 0;
  for (const auto& p : vae->enc_convs->named_parameters())
    if (p.key().find("weight") != std::string::npos) ++n_conv;
  EXPECT_EQ(n_conv, 4);
  EXPECT_EQ(vae->enc_convs->named_parameters()["6.weight"].sizes(), (std::vector<int64_t>{64, 32, 4, 4}));
  EXPECT_EQ(vae->enc_fc->named_parameters()["4.weight"].sizes(), (std::vector<int64_t>{256, 256}));
  EXPECT_EQ(vae->dec_convs->named_parameters()["6.weight"].sizes(), (std::vector<int64_t>{32, 1, 4, 4}));
  torch::Tensor z = torch::zeros({2, 128});
  EXPECT_EQ(vae->decode(z).sizes(), (std::vector<int64_t>{2, 1, 64, 64}));
}

TEST(BetaVae, LossMatchesAHandComputation) {
  // Two latents: mu (1, 0), logvar (0, log 2): KL = 0.5 (1 + 1 - 1 - 0) + 0.5 (0 + 2 - 1 - log 2).
  torch::Tensor mu = torch::tensor({{1.0f, 0.0f}});
  torch::Tensor logvar = torch::tensor({{0.0f, static_cast<float>(std::log(2.0))}});
  const double kl = 0.5 + 0.5 * (1.0 - std::log(2.0));
  // Logits 0.5 everywhere, target 1 on the first half of the pixels, 0 on the rest:
  // BCE = log(1 + e^a) - a y per pixel.
  torch::Tensor logits = torch::full({1, 1, 64, 64}, 0.5f);
  torch::Tensor target = torch::zeros({1, 1, 64, 64});
  target.view({-1}).narrow(0, 0, 2048).fill_(1.0f);
  const double softplus = std::log1p(std::exp(0.5));
  const double bce = 2048 * (softplus - 0.5) + 2048 * softplus;
  VaeLoss l = vae_loss(logits, target, mu, logvar, 6.0);
  EXPECT_NEAR(l.kl.item<double>(), kl, 1e-6);
  EXPECT_NEAR(l.recon.item<double>(), bce, 1e-3);
  EXPECT_NEAR(l.loss.item<double>(), bce + 6.0 * kl, 1e-3);
  // A batch of two equal images has the same per-image loss (mean over the batch).
  VaeLoss l2 = vae_loss(logits.repeat({2, 1, 1, 1}), target.repeat({2, 1, 1, 1}), mu.repeat({2, 1}),
                        logvar.repeat({2, 1}), 6.0);
  EXPECT_NEAR(l2.loss.item<double>(), l.loss.item<double>(), 1e-3);
  // Beta weighs only the KL term.
  VaeLoss l1 = vae_loss(logits, target, mu, logvar, 1.0);
  EXPECT_NEAR(l.loss.item<double>() - l1.loss.item<double>(), 5.0 * kl, 1e-3);
}

TEST(BetaVae, KlPerLatentAndTheActiveCount) {
  // Per latent: 0.5 (mu^2 + sigma^2 - 1 - log sigma^2), by hand.
  torch::Tensor mu = torch::tensor({{1.0f, 0.0f, 0.1f}, {0.0f, 0.0f, 0.0f}});
  torch::Tensor logvar =
      torch::tensor({{0.0f, static_cast<float>(std::log(2.0)), 0.0f}, {0.0f, 0.0f, 0.0f}});
  torch::Tensor kl = kl_per_latent(mu, logvar);
  ASSERT_EQ(kl.sizes(), (std::vector<int64_t>{2, 3}));
  EXPECT_NEAR(kl[0][0].item<double>(), 0.5, 1e-6);
  EXPECT_NEAR(kl[0][1].item<double>(), 0.5 * (1.0 - std::log(2.0)), 1e-6);
  EXPECT_NEAR(kl[0][2].item<double>(), 0.005, 1e-6);
  EXPECT_NEAR(kl[1].abs().sum().item<double>(), 0.0, 1e-7);  // the prior itself: nothing
  // Active: mean KL strictly above 0.01 nats.
  EXPECT_EQ(active_latents({0.5, 0.011, 0.01, 0.0, 0.009}), 2);
  EXPECT_EQ(active_latents({}), 0);
}

TEST(BetaVae, EncoderIsDeterministicAndEvalForwardUsesMu) {
  OneThread one;
  torch::manual_seed(3);
  BetaVae vae(16);
  vae->eval();
  torch::NoGradGuard no_grad;
  torch::Tensor x = (torch::rand({1, 1, 64, 64}) > 0.8).to(torch::kFloat32);
  torch::Tensor a = vae->encode(x).first.contiguous();
  torch::Tensor b = vae->encode(x.clone()).first.contiguous();
  ASSERT_EQ(a.numel(), 16);
  EXPECT_EQ(std::memcmp(a.data_ptr<float>(), b.data_ptr<float>(), 16 * sizeof(float)), 0);
  // Without sampling the decoder sees mu: the same logits as decode(mu).
  VaeOutput o = vae->forward(x, false);
  EXPECT_TRUE(torch::equal(o.logits, vae->decode(a)));
  // Same seed, same weights.
  torch::manual_seed(3);
  BetaVae again(16);
  again->eval();
  EXPECT_TRUE(torch::equal(again->encode(x).first, a));
}

TEST(SpeedPredictor, ShapesAndPerVariableEncoders) {
  OneThread one;
  torch::manual_seed(1);
  SpeedPredictor cim(SpeedPredictorOptions{2, 3, 16, 64});
  EXPECT_EQ(cim->forward(torch::rand({5, 2, 3})).sizes(), (std::vector<int64_t>{5, 1}));
  EXPECT_EQ(cim->enc_weight.sizes(), (std::vector<int64_t>{2, 3, 16}));
  EXPECT_EQ(cim->head->named_parameters()["0.weight"].sizes(), (std::vector<int64_t>{64, 32}));
  SpeedPredictor mlp(SpeedPredictorOptions{128, 3, 8, 64});
  EXPECT_EQ(mlp->forward(torch::rand({4, 128, 3})).sizes(), (std::vector<int64_t>{4, 1}));
  EXPECT_EQ(mlp->head->named_parameters()["0.weight"].sizes(), (std::vector<int64_t>{64, 128 * 8}));

  // Each variable has its own encoder: changing variable 1's history leaves variable 0's
  // encoding alone, and the output equals the hand-written relu(x_v W_v + b_v) -> MLP.
  torch::NoGradGuard no_grad;
  torch::Tensor x = torch::rand({3, 2, 3});
  torch::Tensor h0 = torch::relu(x.select(1, 0).matmul(cim->enc_weight[0]) + cim->enc_bias[0]);
  torch::Tensor h1 = torch::relu(x.select(1, 1).matmul(cim->enc_weight[1]) + cim->enc_bias[1]);
  torch::Tensor expect = cim->head->forward(torch::cat({h0, h1}, 1));
  EXPECT_TRUE(torch::allclose(cim->forward(x), expect, 1e-5, 1e-6));
  EXPECT_THROW(SpeedPredictor(SpeedPredictorOptions{0, 3, 16, 64}), std::exception);
}

}  // namespace
}  // namespace cd
