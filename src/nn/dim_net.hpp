#pragma once
// DIM (Rhinehart et al., "Deep Imitative Models"), the imitative trajectory density of seed
// 000's baselines, in R2P2's autoregressive form, sized for a CPU.
//
//   frame (C planes of 0/1) -> SmallBackbone -> f (features)
//   [f, past / 10 m] -> Linear -> c (hidden): what the observation says, computed once
//   step k = 1..H:  h_k = ReLU(c + Wz (z_{<k} / 10 m, later positions masked out) + e_k)
//                   (m_k, s_k) = Linear(ReLU(Linear(h_k)))
//                   z_k ~ N(2 z_{k-1} - z_{k-2} + m_k, diag(min_std + softplus(s_k))^2)
//
// z_k is the ego-frame position (m, x forward, y left) k*waypoint_step steps ahead; z_0 = 0 is
// the ego now and z_{-1} = past_1 its position one waypoint step ago, so m = 0 is the verlet
// (constant velocity) prediction. Because step k sees z_{<k} through a mask and no recurrence,
// log q(z) of a given z is one batched pass over the horizon (training and planning), and only
// sampling/the mean rollout is sequential. The per-step head takes its weights as stacked
// tensors with a leading member axis, so an ensemble (rip) is evaluated in one pass.
//
// This header includes torch: include it only from .cpp files that run the network.
#include <string>
#include <vector>

#include <torch/torch.h>

#include "nn/model_settings.hpp"
#include "nn/policy_net.hpp"

namespace cd {

struct DimNetOptions {
  int channels = 8, height = 64, width = 64;
  int horizon = 4, past = 4, features = 128, hidden = 128;
  double min_std = 0.05;
};

// The network of the [dim] settings for frames of C x H x W.
inline DimNetOptions dim_net_options(const DimSettings& d, int channels, int height, int width) {
  DimNetOptions o;
  o.channels = channels;
  o.height = height;
  o.width = width;
  o.horizon = d.horizon;
  o.past = d.past;
  o.features = d.features;
  o.hidden = d.hidden;
  o.min_std = d.min_std;
  return o;
}

// What an observation conditions the density on. context: K x B x hidden (K members; K = 1
// for one net), past1: B x 2, the position one waypoint step ago (the verlet term).
struct DimCondition {
  torch::Tensor context, past1;
};

// Per-step Gaussians, K x B x H x 2 each (m).
struct DimGaussians {
  torch::Tensor mean, std;
};

// The per-step head's weights, each with a leading member axis K.
struct DimHeadWeights {
  torch::Tensor wz;   // K x 2H x hidden
  torch::Tensor emb;  // K x H x hidden (step embedding, also the first layer's bias)
  torch::Tensor w2;   // K x hidden x hidden
  torch::Tensor b2;   // K x hidden
  torch::Tensor w3;   // K x hidden x 4
  torch::Tensor b3;   // K x 4
};

struct DimNetImpl : torch::nn::Module {
  explicit DimNetImpl(const DimNetOptions& options);

  // frames: B x C x H x W (0/1) -> B x features.
  torch::Tensor encode(const torch::Tensor& frames);
  // features: B x features, past: B x P x 2 (m, ego frame, past_1 first) -> K = 1 condition.
  DimCondition condition(const torch::Tensor& features, const torch::Tensor& past);
  // z: B x H x 2 -> K=1 x B x H x 2 Gaussians of each step given the steps before it.
  DimGaussians gaussians(const DimCondition& c, const torch::Tensor& z);
  // log q(z | o) in nats, B values; differentiable in z and the weights.
  torch::Tensor log_prob(const DimCondition& c, const torch::Tensor& z);
  torch::Tensor log_prob(const torch::Tensor& features, const torch::Tensor& past,
                         const torch::Tensor& z);
  // The trajectory of step means (each step conditioned on the previous means): B x H x 2.
  torch::Tensor mean_rollout(const DimCondition& c);

  // This net's head weights viewed with K = 1 (shares storage and gradients).
  DimHeadWeights head_weights() const;
  const DimNetOptions& options() const { return options_; }

  SmallBackbone backbone{nullptr};
  torch::nn::Linear cond{nullptr};
  torch::Tensor wz, emb, w2, b2, w3, b3;

 private:
  DimNetOptions options_;
};
TORCH_MODULE(DimNet);

// The head over K members at once. z: B x H x 2 (shared) or K x B x H x 2.
DimGaussians dim_gaussians(const DimHeadWeights& w, const DimCondition& c, const torch::Tensor& z,
                           double min_std);
// Sum over steps and coordinates of log N(z | mean, std): K x B.
torch::Tensor dim_log_prob(const DimGaussians& g, const torch::Tensor& z);
// Each member's own mean rollout: K x B x H x 2.
torch::Tensor dim_mean_rollout(const DimHeadWeights& w, const DimCondition& c, int horizon,
                               double min_std);

// K trained members (eval mode, no gradients to their weights) evaluated together.
class DimEnsemble {
 public:
  explicit DimEnsemble(std::vector<DimNet> members);
  int size() const { return static_cast<int>(members_.size()); }
  const DimNetOptions& options() const { return members_.front()->options(); }
  DimNet& member(int k) { return members_[k]; }

  // frame: 1 x C x H x W (0/1), past: 1 x P x 2 -> condition with K = size().
  DimCondition condition(const torch::Tensor& frame, const torch::Tensor& past);
  // log q_k(z | o) of every member: K x B (z: B x H x 2).
  torch::Tensor log_probs(const DimCondition& c, const torch::Tensor& z) const;
  torch::Tensor mean_rollouts(const DimCondition& c) const;  // K x B x H x 2

 private:
  std::vector<DimNet> members_;
  DimHeadWeights stacked_;
};

// agg over members of log q (K x B -> B): "worst" = min (RIP), "mean" = average.
torch::Tensor aggregate_log_q(const torch::Tensor& log_q, const std::string& aggregation);

struct DimPlanOptions {
  int iterations = 30;
  double lr = 0.2;             // Adam step (m)
  double goal_weight = 0.02;   // per m^2
  std::string aggregation = "worst";
  bool segment_goal = false;   // the goal term on the segment [0, goal] instead of the point
};

struct DimPlan {
  torch::Tensor z;                   // H x 2, the plan (the best iterate by the objective)
  double objective_before = 0;       // J(z0)
  double objective_after = 0;        // J(z) >= J(z0)
  double moved_m = 0;                // mean distance between z and z0 over the waypoints
  std::vector<double> log_q_before;  // per member, at z0
  std::vector<double> log_q_after;   // per member, at z
};

// Maximises J(z) = agg_k log q_k(z | o) - goal_weight |z_H - goal|^2 (segment_goal: the
// squared distance of z_H from the segment [0, goal]) by Adam from z0 (H x 2;
// undefined: the mean rollout of member 0). c: the ensemble's condition for one observation;
// goal: 2 values (m, ego frame).
DimPlan plan_trajectory(const DimEnsemble& ensemble, const DimCondition& c,
                        const torch::Tensor& goal, const DimPlanOptions& options,
                        torch::Tensor z0 = {});

// The speed a plan implies, m/s, never negative: |z_1| / (waypoint_step * dt), or with
// over_horizon the length of the polyline 0, z_1..z_H / (H * waypoint_step * dt).
double implied_speed(const torch::Tensor& z, int waypoint_step, double dt,
                     bool over_horizon = false);

// The squared distance of point p (2) from the segment [0, g] (differentiable in p).
torch::Tensor squared_distance_to_segment(const torch::Tensor& p, const torch::Tensor& g);

}  // namespace cd
