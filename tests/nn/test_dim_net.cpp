// The trajectory density of dim / rip (nn/dim_net): autoregressive Gaussians, log q by hand,
// the mean rollout, a one-member ensemble.
#include "nn/dim_net.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include <torch/torch.h>

#include "inference/policy_runner.hpp"

namespace cd {
namespace {

class DimNetTest : public ::testing::Test {
 protected:
  void SetUp() override { set_torch_threads(1); }
};

TEST_F(DimNetTest, DensityIsAutoregressiveAndTheEnsembleMatchesItsMembers) {
  torch::manual_seed(1);
  DimNetOptions o{.channels = 8, .height = 32, .width = 32, .horizon = 4, .past = 4,
                  .features = 16, .hidden = 32};
  DimNet net(o);
  net->eval();
  torch::NoGradGuard no_grad;
  torch::Tensor frame = (torch::rand({2, 8, 32, 32}) > 0.5).to(torch::kFloat32);
  torch::Tensor past = torch::randn({2, 4, 2});
  torch::Tensor z = torch::randn({2, 4, 2}) * 3;
  DimCondition c = net->condition(net->encode(frame), past);
  DimGaussians g = net->gaussians(c, z);
  // Changing z_3 leaves the Gaussians of steps 1..3 as they were and changes step 4's.
  torch::Tensor z2 = z.clone();
  z2.index_put_({torch::indexing::Slice(), 2}, z2.index({torch::indexing::Slice(), 2}) + 1.5);
  DimGaussians g2 = net->gaussians(c, z2);
  EXPECT_TRUE(torch::allclose(g.mean.narrow(2, 0, 3), g2.mean.narrow(2, 0, 3)));
  EXPECT_TRUE(torch::allclose(g.std.narrow(2, 0, 3), g2.std.narrow(2, 0, 3)));
  EXPECT_FALSE(torch::allclose(g.mean.narrow(2, 3, 1), g2.mean.narrow(2, 3, 1)));
  EXPECT_GE(g.std.min().item<double>(), o.min_std);
  // log q equals the sum of per-coordinate normal log densities.
  torch::Tensor u = (z.unsqueeze(0) - g.mean) / g.std;
  torch::Tensor manual = (-0.5 * u.square() - g.std.log() - 0.5 * std::log(2 * M_PI)).sum({2, 3});
  EXPECT_TRUE(torch::allclose(net->log_prob(c, z), manual.squeeze(0), 1e-5, 1e-4));
  // The mean rollout is the fixed point of its own means.
  torch::Tensor m = net->mean_rollout(c);
  EXPECT_TRUE(torch::allclose(net->gaussians(c, m).mean.squeeze(0), m, 1e-5, 1e-5));
  // A one-member ensemble gives the net's own log q.
  DimEnsemble ens({net});
  DimCondition ce = ens.condition(frame.narrow(0, 0, 1), past.narrow(0, 0, 1));
  EXPECT_TRUE(torch::allclose(ens.log_probs(ce, z.narrow(0, 0, 1)).squeeze(0),
                              net->log_prob(c, z).narrow(0, 0, 1), 1e-5, 1e-4));
}

}  // namespace
}  // namespace cd
