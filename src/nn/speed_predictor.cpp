#include "nn/speed_predictor.hpp"

#include <cmath>

#include "core/error.hpp"

namespace cd {

SpeedPredictorImpl::SpeedPredictorImpl(const SpeedPredictorOptions& o) : options_(o) {
  if (o.variables < 1 || o.history < 1 || o.units < 1 || o.hidden < 1)
    throw ConfigError("speed predictor: variables, history, units and hidden must be >= 1");
  // torch::nn::Linear's default initialisation: U(-1/sqrt(fan_in), 1/sqrt(fan_in)).
  const double bound = 1.0 / std::sqrt(static_cast<double>(o.history));
  enc_weight = register_parameter(
      "enc_weight", torch::empty({o.variables, o.history, o.units}).uniform_(-bound, bound));
  enc_bias = register_parameter("enc_bias",
                                torch::empty({o.variables, o.units}).uniform_(-bound, bound));
  head = register_module(
      "head", torch::nn::Sequential(torch::nn::Linear(o.variables * o.units, o.hidden),
                                    torch::nn::ReLU(), torch::nn::Linear(o.hidden, 1)));
}

torch::Tensor SpeedPredictorImpl::forward(const torch::Tensor& x) {
  // (V x B x H) @ (V x H x U) -> V x B x U, then B x V x U.
  torch::Tensor h = torch::bmm(x.transpose(0, 1), enc_weight).transpose(0, 1) + enc_bias;
  h = torch::relu(h).flatten(1);
  return head->forward(h);
}

}  // namespace cd
