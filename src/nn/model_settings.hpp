#pragma once
// The settings of the networks and what they see ([model], [vae], [dim], [residual], [fca]);
// torch-free.
#include <string>

namespace cd {

// The network of the behaviour-cloning methods (bc-so, bc-oh) and what it sees.
struct ModelSettings {
  std::string backbone = "small";  // small (CPU-sized CNN) | resnet34 (the seeds', GPU)
  // What reads the backbone's feature: "cilrs" (speed input MLP, fusion layer and one MLP branch
  // per command: seed 001's driving model, fig. 5) or "linear" (one linear layer from the feature
  // to the action: seed 001's MuJoCo model, fig. 10; no command branches, no speed input).
  std::string head = "cilrs";
  int history = 4;                 // frames stacked by bc-oh (bc-so: 1)
  int history_stride = 2;          // simulation steps between stacked frames
  std::string action_head = "throttle_brake";  // throttle_brake | target_speed
  // How a throttle_brake head learns driving's throttle and brake: "two" (as recorded, two
  // sigmoids) or "signed" (one value throttle - brake in [-1, 1], tanh: the seeds' public code's
  // throttle_brake; a policy can then never press both, and standing's brake label -0.3 is
  // inside the squash's range, not at a saturated end). Steer, when recorded, follows it.
  // "auto" (the default, the validated recipe's): "signed" for driving data through a
  // throttle_brake head, "two" otherwise; a trained run records the value it resolved to.
  std::string pedals = "auto";
  bool speed_input = false;        // false: the measured speed is zeroed (the seeds' POMDP)
  int features = 256;              // width of the backbone's output and the branches
  double speed_loss_weight = 0.05; // auxiliary speed-prediction head
  double dropout = 0.2;
};

// model.pedals = "signed" (or "auto") applies to driving data learned through a throttle_brake
// head.
inline bool signed_pedals(const ModelSettings& m, const std::string& domain) {
  return (m.pedals == "signed" || m.pedals == "auto") && m.action_head == "throttle_brake" &&
         domain == "driving";
}
// A recorded driving action (throttle, brake[, steer]) as a signed-pedals policy learns it
// (throttle - brake[, steer]), and back (throttle = max(v, 0), brake = max(-v, 0)).
// `recorded_dim` counts the recorded components (>= 2).
inline void pedals_to_learned(const float* recorded, int recorded_dim, float* learned) {
  learned[0] = recorded[0] - recorded[1];
  for (int i = 2; i < recorded_dim; ++i) learned[i - 1] = recorded[i];
}
inline void pedals_to_recorded(const float* learned, int recorded_dim, float* recorded) {
  const float v = learned[0];
  for (int i = recorded_dim - 1; i >= 2; --i) recorded[i] = learned[i - 1];
  recorded[0] = v > 0 ? v : 0.0f;
  recorded[1] = v < 0 ? -v : 0.0f;
}

// Perception model of the cim family (seed 000 section 5.4.2): a beta-VAE on one grey BEV view.
struct VaeSettings {
  std::string view = "vehicles";  // BEV channel(s) merged into the grey input, "a+b" for several
  int latents = 128;
  double beta = 6.0;     // cim and cim-mlp; cim-entangled trains with beta = 1
  int epochs = 4;        // at most; fewer when the patience rule stops it
  int patience = 0;      // stop after this many epochs in a row whose loss fell by less than
                         // min_improvement of the last clear improvement; 0: train every epoch
  double min_improvement = 0.01;
  int batch_size = 64;
  double lr = 1e-3;
  long max_frames = 30000;  // seeded subset of the data's frames it trains on, 0 = all
};

// The imitative trajectory model (dim) and its ensemble (rip), seed 000 section 5.3.
struct DimSettings {
  int horizon = 4;          // future waypoints predicted
  int waypoint_step = 5;    // simulation steps between waypoints (0.5 s at dt 0.1)
  int past = 4;             // past ego positions it is conditioned on
  int features = 128;       // width of the BEV encoder output
  int hidden = 128;
  double min_std = 0.05;    // m, lower bound of each step's standard deviation
  int plan_iterations = 10; // gradient-ascent steps of the planner
  int replan_steps = 2;     // the agent plans every this many simulation steps
  double plan_lr = 0.2;     // m per step (Adam)
  double goal_distance = 20;  // m along the route: the goal the plan is pulled toward
  double goal_weight = 0.02;  // weight of the goal term (per m^2) in the objective
  // The goal term: "point" -goal_weight |z_H - g|^2 (a Gaussian goal at the route point g);
  // "segment" -goal_weight d(z_H, [0, g])^2 (DIM's line-segment goal: a Gaussian around the
  // straight line from the ego to g, flat along it, so it steers without asking for speed).
  std::string goal = "point";
  // The target speed a plan implies: "first" |z_1| over its time; "horizon" the length of the
  // polyline 0, z_1..z_H over the horizon's time (the plan's mean speed).
  std::string plan_speed = "first";
  int ensemble = 3;           // rip: DIMs trained on bootstrap resamples of the episodes
  int patience = 0;  // a member stops after this many epochs without a better validation
                     // NLL (train.epochs at most); 0: every epoch
  std::string aggregation = "worst";  // rip: worst (min over members) | mean
  // The BEV channels the model sees, "a+b" (sense/grey_view.hpp); the others are blank.
  // Empty: all of them. "vehicles" matches cim's default view (a like-for-like baseline).
  std::string view;
};

// residual (appendix B.1, figure 6, equation 5) and its ablations (B.2, B.5, table 11).
struct ResidualSettings {
  // Heads of the memory module: a_t - a_{t-i} for i = 1..branches (appendix B.5).
  int branches = 1;
  // What the memory module learns (figure 8): "residual" (a_t - a_{t-1}, the method),
  // "action" (a_t) or "previous" (a_{t-1}).
  std::string memory_target = "residual";
  // What acts (figure 7): "stream" (the policy module on the current frame plus the detached
  // memory feature, the method), "residual_controller" (memory only: a_{t-1} + its predicted
  // residual), "learned_controller" (memory only: a 3-layer MLP on the detached memory feature
  // learns a_t).
  std::string policy = "stream";
  // What the policy stream sees: "current" (the current frame only, the method) or "history"
  // (the same frames as the memory module: the two-stream bc-oh / keyframe of table 11).
  std::string policy_input = "current";
  // Per-sample weights of the policy loss: "none", or "keyframe" (the keyframe method's
  // weights: two-stream keyframe, table 11).
  std::string weights = "none";
};

// fca: adversarial removal of the previous action from the history feature.
struct FcaSettings {
  double adversary_weight = 2.0;  // w in L_policy - w * L_adversary (public Hopper run)
  int hidden = 300;               // adversary MLP width (public code)
  double beta1 = 0.5;             // Adam beta1 of every fca parameter (public code: 0.5, 0.999)
};

}  // namespace cd
