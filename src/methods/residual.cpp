// residual (seed 001, appendix B.1, figure 6, equation 5): a memory-extraction module M reads
// the frame history and learns the action residual a_t - a_{t-1} (plus the speed head); its
// backbone feature, detached, joins the policy module pi, which sees the current frame only
// and learns a_t (plus the speed head). L = L_M + L_pi. No gradient of L_pi reaches M: the
// policy gets the history's information only as far as it predicts the change of action,
// not the previous action itself (the copycat shortcut).
//
// One Adam holds both modules: with the feature detached, each module's gradient is that of
// its own loss, which is the public code's two optimisers stepped one after the other.
// Ablations, as settings of this code ([residual]): residual.branches adds the heads
// a_t - a_{t-i} (B.5); memory_target = action | previous (figure 8); policy =
// residual_controller | learned_controller (memory only, figure 7); policy_input = history and
// weights = keyframe (the two-stream bc-oh and keyframe of table 11).
#include <algorithm>
#include <optional>

#include "methods/policy_family.hpp"

namespace cd {

torch::Tensor memory_targets(const std::string& target, const torch::Tensor& action,
                             const torch::Tensor& previous, int heads) {
  if (target == "action") return action;
  if (target == "previous") return previous.select(1, 0);
  std::vector<torch::Tensor> diffs;
  for (int i = 0; i < heads; ++i) diffs.push_back(action - previous.select(1, i));
  return torch::cat(diffs, 1);
}

ResidualLosses residual_losses(PolicyNets& nets, const PolicyBatch& b, const Settings& s,
                               int frame_channels, const torch::Tensor& w) {
  const PolicyNetsLayout& l = nets.layout;
  PolicyOutput mem = nets.memory->forward(b.image, b.speed_in, b.command, true);
  torch::Tensor target = memory_targets(l.memory_target, b.action, b.previous, l.memory_heads);
  ResidualLosses out;
  out.memory = policy_loss(s, mem, target, b.speed_label, sample_weights(b));
  const torch::Tensor feature = mem.feature.detach();
  if (nets.policy) {
    torch::Tensor in = l.policy_sees_history ? b.image : b.current(frame_channels);
    PolicyOutput act = nets.policy->forward(in, b.speed_in, b.command, true, feature);
    out.act = policy_loss(s, act, b.action, b.speed_label, w);
  } else if (nets.controller) {
    out.act = action_loss(s.train.loss, nets.control(feature), b.action, w);
  } else {
    out.act = torch::zeros({}, out.memory.options());  // residual controller: M alone acts
  }
  return out;
}

namespace {

class ResidualObjective : public Objective {
 public:
  ResidualObjective(FamilyContext& c, nlohmann::json& record) : c_(c) {
    if (c.settings.residual.weights == "keyframe") weights_.emplace(c, record);
  }
  void set_training(bool on) override { c_.nets.set_training(on); }

  BatchLoss loss(bool training, const uint32_t* rows, int64_t n) override {
    PolicyBatch b = c_.batcher.batch(training, rows, n);
    torch::Tensor w = sample_weights(b, training && weights_ ? weights_->of(b) : torch::Tensor());
    ResidualLosses l = residual_losses(c_.nets, b, c_.settings, c_.data.episodes().channels, w);
    return {l.memory + l.act, {l.memory, l.act}};
  }

 private:
  FamilyContext& c_;
  std::optional<KeyframeWeights> weights_;
};

}  // namespace

TrainSummary train_residual(const Settings& settings, const TrainRequest& req) {
  FamilyMethod m;
  m.tables = {"residual"};
  if (settings.residual.weights == "keyframe") m.tables.push_back("keyframe");
  m.action_lags = [](const Settings& s) {
    const ResidualSettings& r = s.residual;
    int lags = r.memory_target == "residual" ? r.branches : r.memory_target == "previous" ? 1 : 0;
    if (r.weights == "keyframe") lags = std::max(lags, s.keyframe.actions);
    return lags;
  };
  m.objective = [](FamilyContext& c, nlohmann::json& record) -> std::unique_ptr<Objective> {
    return std::make_unique<ResidualObjective>(c, record);
  };
  return train_policy_family(settings, req, m);
}

}  // namespace cd
