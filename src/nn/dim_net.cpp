#include "nn/dim_net.hpp"

#include <cmath>
#include <limits>

#include "core/error.hpp"

namespace cd {

namespace {

constexpr double kPositionScale = 10.0;  // m: positions enter the layers divided by this
const double kHalfLog2Pi = 0.5 * std::log(2.0 * M_PI);

torch::Tensor uniform_param(std::vector<int64_t> shape, double bound) {
  return torch::empty(shape).uniform_(-bound, bound);
}

// Row k (step k+1) keeps the coordinates of z_1..z_k: columns j < 2k.
torch::Tensor causal_mask(int64_t horizon, const torch::TensorOptions& o) {
  auto cols = torch::arange(2 * horizon, o).unsqueeze(0);
  auto rows = torch::arange(horizon, o).unsqueeze(1);
  return (cols < 2 * rows).to(o.dtype());
}

}  // namespace

DimNetImpl::DimNetImpl(const DimNetOptions& o) : options_(o) {
  if (o.horizon < 1 || o.past < 1)
    throw ConfigError("dim: horizon and past must be at least 1");
  backbone = register_module("backbone", SmallBackbone(o.channels, o.height, o.width, o.features));
  cond = register_module("cond", torch::nn::Linear(o.features + 2 * o.past, o.hidden));
  const double in_bound = 1.0 / std::sqrt(static_cast<double>(2 * o.horizon));
  const double hid_bound = 1.0 / std::sqrt(static_cast<double>(o.hidden));
  wz = register_parameter("wz", uniform_param({2 * o.horizon, o.hidden}, in_bound));
  emb = register_parameter("emb", uniform_param({o.horizon, o.hidden}, hid_bound));
  w2 = register_parameter("w2", uniform_param({o.hidden, o.hidden}, hid_bound));
  b2 = register_parameter("b2", torch::zeros({o.hidden}));
  // A small last layer: training starts near the verlet prediction with std min_std + log 2.
  w3 = register_parameter("w3", uniform_param({o.hidden, 4}, 0.1 * hid_bound));
  b3 = register_parameter("b3", torch::zeros({4}));
}

torch::Tensor DimNetImpl::encode(const torch::Tensor& frames) { return backbone->forward(frames); }

DimCondition DimNetImpl::condition(const torch::Tensor& features, const torch::Tensor& past) {
  torch::Tensor x = torch::cat({features, past.flatten(1) / kPositionScale}, 1);
  return {cond->forward(x).unsqueeze(0), past.select(1, 0)};
}

DimHeadWeights DimNetImpl::head_weights() const {
  return {wz.unsqueeze(0), emb.unsqueeze(0), w2.unsqueeze(0),
          b2.unsqueeze(0), w3.unsqueeze(0), b3.unsqueeze(0)};
}

DimGaussians DimNetImpl::gaussians(const DimCondition& c, const torch::Tensor& z) {
  return dim_gaussians(head_weights(), c, z, options_.min_std);
}

torch::Tensor DimNetImpl::log_prob(const DimCondition& c, const torch::Tensor& z) {
  return dim_log_prob(gaussians(c, z), z).squeeze(0);
}

torch::Tensor DimNetImpl::log_prob(const torch::Tensor& features, const torch::Tensor& past,
                                   const torch::Tensor& z) {
  return log_prob(condition(features, past), z);
}

torch::Tensor DimNetImpl::mean_rollout(const DimCondition& c) {
  return dim_mean_rollout(head_weights(), c, options_.horizon, options_.min_std).squeeze(0);
}

DimGaussians dim_gaussians(const DimHeadWeights& w, const DimCondition& c, const torch::Tensor& z,
                           double min_std) {
  const int64_t K = w.wz.size(0), H = w.emb.size(1);
  const torch::Tensor z4 = z.dim() == 3 ? z.unsqueeze(0) : z;  // Kz x B x H x 2, Kz in {1, K}
  const int64_t Kz = z4.size(0), B = z4.size(1);
  if (z4.size(2) != H || z4.size(3) != 2)
    throw Error("dim: trajectory of shape " + std::to_string(z4.size(2)) + "x" +
                std::to_string(z4.size(3)) + " for a horizon of " + std::to_string(H));
  const torch::Tensor mask = causal_mask(H, z4.options());
  const torch::Tensor zin = z4.reshape({Kz, B, 1, 2 * H}) * mask / kPositionScale;  // Kz B H 2H
  torch::Tensor h = torch::matmul(zin, w.wz.unsqueeze(1)) + c.context.unsqueeze(2) +
                    w.emb.unsqueeze(1);  // K x B x H x hidden
  h = torch::relu(h);
  h = torch::relu(torch::matmul(h, w.w2.unsqueeze(1)) + w.b2.view({K, 1, 1, -1}));
  const torch::Tensor o = torch::matmul(h, w.w3.unsqueeze(1)) + w.b3.view({K, 1, 1, 4});
  // (z_{-1}, z_0, z_1 .. z_H): step k's verlet base is 2 z_{k-1} - z_{k-2}.
  const torch::Tensor p1 = c.past1.view({1, -1, 1, 2}).expand({Kz, B, 1, 2});  // 1 or B rows
  const torch::Tensor seq = torch::cat({p1, torch::zeros_like(p1), z4}, 2);
  DimGaussians g;
  g.mean = 2 * seq.narrow(2, 1, H) - seq.narrow(2, 0, H) + o.narrow(3, 0, 2);
  g.std = min_std + torch::softplus(o.narrow(3, 2, 2));
  return g;
}

torch::Tensor dim_log_prob(const DimGaussians& g, const torch::Tensor& z) {
  const torch::Tensor z4 = z.dim() == 3 ? z.unsqueeze(0) : z;
  const torch::Tensor u = (z4 - g.mean) / g.std;
  return (-0.5 * u.square() - g.std.log() - kHalfLog2Pi).sum({2, 3});
}

torch::Tensor dim_mean_rollout(const DimHeadWeights& w, const DimCondition& c, int horizon,
                               double min_std) {
  const int64_t K = w.wz.size(0), B = c.past1.size(0);
  torch::Tensor z = torch::zeros({K, B, horizon, 2}, c.past1.options());
  for (int k = 0; k < horizon; ++k) {
    // Step k depends on z_{<k} only, which are already the means.
    DimGaussians g = dim_gaussians(w, c, z, min_std);
    z = torch::cat({g.mean.narrow(2, 0, k + 1), z.narrow(2, k + 1, horizon - k - 1)}, 2);
  }
  return z;
}

DimEnsemble::DimEnsemble(std::vector<DimNet> members) : members_(std::move(members)) {
  if (members_.empty()) throw Error("dim: an ensemble needs at least one member");
  std::vector<torch::Tensor> wz, emb, w2, b2, w3, b3;
  for (auto& m : members_) {
    m->eval();
    for (auto& p : m->parameters()) p.set_requires_grad(false);
    wz.push_back(m->wz);
    emb.push_back(m->emb);
    w2.push_back(m->w2);
    b2.push_back(m->b2);
    w3.push_back(m->w3);
    b3.push_back(m->b3);
  }
  stacked_ = {torch::stack(wz), torch::stack(emb), torch::stack(w2),
              torch::stack(b2), torch::stack(w3), torch::stack(b3)};
}

DimCondition DimEnsemble::condition(const torch::Tensor& frame, const torch::Tensor& past) {
  torch::NoGradGuard no_grad;
  std::vector<torch::Tensor> contexts;
  torch::Tensor past1;
  for (auto& m : members_) {
    DimCondition c = m->condition(m->encode(frame), past);
    contexts.push_back(c.context.squeeze(0));
    past1 = c.past1;
  }
  return {torch::stack(contexts), past1};
}

torch::Tensor DimEnsemble::log_probs(const DimCondition& c, const torch::Tensor& z) const {
  return dim_log_prob(dim_gaussians(stacked_, c, z, options().min_std), z);
}

torch::Tensor DimEnsemble::mean_rollouts(const DimCondition& c) const {
  torch::NoGradGuard no_grad;
  return dim_mean_rollout(stacked_, c, options().horizon, options().min_std);
}

torch::Tensor aggregate_log_q(const torch::Tensor& log_q, const std::string& aggregation) {
  if (aggregation == "worst") return std::get<0>(log_q.min(0));
  if (aggregation == "mean") return log_q.mean(0);
  throw ConfigError("dim.aggregation must be worst or mean (got '" + aggregation + "')");
}

DimPlan plan_trajectory(const DimEnsemble& ensemble, const DimCondition& c,
                        const torch::Tensor& goal, const DimPlanOptions& o, torch::Tensor z0) {
  const int64_t H = ensemble.options().horizon;
  torch::AutoGradMode grad_on(true);  // also when the caller holds a NoGradGuard
  if (!z0.defined()) z0 = ensemble.mean_rollouts(c).select(0, 0).select(0, 0);
  torch::Tensor z = z0.detach().reshape({1, H, 2}).clone().set_requires_grad(true);
  const torch::Tensor g = goal.detach().reshape({2});

  DimPlan plan;
  plan.objective_after = -std::numeric_limits<double>::infinity();
  auto to_vector = [](const torch::Tensor& t) {
    torch::Tensor d = t.detach().to(torch::kFloat64).contiguous();
    return std::vector<double>(d.data_ptr<double>(), d.data_ptr<double>() + d.numel());
  };
  // Evaluates J at z; keeps z as the plan when it is the best so far.
  auto objective = [&](bool first) {
    torch::Tensor log_q = ensemble.log_probs(c, z).select(1, 0);  // K
    const torch::Tensor last = z.select(0, 0).select(0, H - 1);
    const torch::Tensor off_goal = o.segment_goal ? squared_distance_to_segment(last, g)
                                                  : (last - g).square().sum();
    torch::Tensor j =
        aggregate_log_q(log_q.unsqueeze(1), o.aggregation).squeeze(0) - o.goal_weight * off_goal;
    const double jv = j.item<double>();
    if (first) {
      plan.objective_before = jv;
      plan.log_q_before = to_vector(log_q);
    }
    if (jv > plan.objective_after) {
      plan.objective_after = jv;
      plan.log_q_after = to_vector(log_q);
      plan.z = z.detach().select(0, 0).clone();
    }
    return j;
  };

  torch::optim::Adam opt(std::vector<torch::Tensor>{z}, torch::optim::AdamOptions(o.lr));
  for (int i = 0; i < o.iterations; ++i) {
    torch::Tensor j = objective(i == 0);
    opt.zero_grad();
    (-j).backward();
    opt.step();
  }
  {
    torch::NoGradGuard no_grad;
    objective(o.iterations == 0);
    plan.moved_m = (plan.z - z0.detach().reshape({H, 2})).norm(2, {1}).mean().item<double>();
  }
  return plan;
}

double implied_speed(const torch::Tensor& z, int waypoint_step, double dt, bool over_horizon) {
  // The plan's legs 0 -> z_1 -> ... -> z_H; the first one alone, or all of them.
  const torch::Tensor w = z.detach().to(torch::kFloat64);
  const int64_t legs = over_horizon ? w.size(0) : 1;
  const torch::Tensor pts = torch::cat({torch::zeros({1, 2}, w.options()), w.narrow(0, 0, legs)}, 0);
  const double length = pts.diff(1, 0).norm(2, {1}).sum().item<double>();
  return std::max(0.0, length / (static_cast<double>(legs) * waypoint_step * dt));
}

torch::Tensor squared_distance_to_segment(const torch::Tensor& p, const torch::Tensor& g) {
  // t = 0 for a degenerate segment (g = 0): the distance to the point 0.
  const torch::Tensor t = ((p * g).sum() / g.square().sum().clamp_min(1e-12)).clamp(0.0, 1.0);
  return (p - t * g).square().sum();
}

}  // namespace cd
