// fca (Wen et al., "Fighting copycat agents in behavioral cloning from observation histories"):
// the history encoder E (the policy network up to its fusion layer, whose output j the
// branches read) and the policy head F learn the action while an adversary D tries to
// recover the previous action a_{t-1} from [j, a_t]. Each batch takes two alternating steps
// (as the public code does):
//   D step      D minimises its squared error on the detached embedding;
//   E + F step  E and F minimise L_policy - fca.adversary_weight * L_D with D held fixed,
// so E learns features from which a_{t-1} cannot be read beyond what a_t already says.
// One Adam holds every parameter; a step leaves the parameters whose gradients were cleared
// untouched, so this is the public code's two optimisers (betas 0.5, 0.999 there).
#include "methods/policy_family.hpp"

namespace cd {

void clear_grads(const std::vector<torch::Tensor>& params) {
  for (const torch::Tensor& p : params) {
    torch::Tensor& g = const_cast<torch::Tensor&>(p).mutable_grad();
    g = torch::Tensor();
  }
}

torch::Tensor fca_adversary_loss(torch::nn::Sequential& adversary, const torch::Tensor& embedding,
                                 const torch::Tensor& action, const torch::Tensor& previous_action) {
  torch::Tensor guess = adversary->forward(torch::cat({embedding, action}, 1));
  return (guess - previous_action).pow(2).sum(1).mean();
}

FcaLosses fca_step(PolicyNets& nets, torch::optim::Optimizer& opt, const PolicyBatch& b,
                   const Settings& s, double clip) {
  const std::vector<torch::Tensor> all = nets.parameters(), adv = nets.adversary_parameters();
  const torch::Tensor prev = b.previous.select(1, 0);
  PolicyOutput out = nets.policy->forward(b.image, b.speed_in, b.command, true);

  // D step.
  clear_grads(all);
  torch::Tensor d_loss = fca_adversary_loss(nets.adversary, out.embedding.detach(), b.action, prev);
  d_loss.backward();
  if (clip > 0) torch::nn::utils::clip_grad_norm_(adv, clip);
  opt.step();

  // E + F step against the updated D, which stays as it is.
  clear_grads(all);
  torch::Tensor p_loss = policy_loss(s, out, b.action, b.speed_label, sample_weights(b));
  torch::Tensor fooled = fca_adversary_loss(nets.adversary, out.embedding, b.action, prev);
  (p_loss - s.fca.adversary_weight * fooled).backward();
  clear_grads(adv);
  if (clip > 0) torch::nn::utils::clip_grad_norm_(all, clip);
  opt.step();
  clear_grads(all);
  return {p_loss.detach(), d_loss.detach()};
}

namespace {

class FcaObjective : public Objective {
 public:
  explicit FcaObjective(FamilyContext& c) : c_(c) {}
  void set_training(bool on) override { c_.nets.set_training(on); }

  // The policy loss (what selects the best epoch) and, as a part, D's loss.
  BatchLoss loss(bool training, const uint32_t* rows, int64_t n) override {
    PolicyBatch b = c_.batcher.batch(training, rows, n);
    PolicyOutput out = c_.nets.policy->forward(b.image, b.speed_in, b.command, true);
    torch::Tensor d = fca_adversary_loss(c_.nets.adversary, out.embedding, b.action,
                                         b.previous.select(1, 0));
    return {policy_loss(c_.settings, out, b.action, b.speed_label), {d}};
  }

  BatchLoss update(const uint32_t* rows, int64_t n, torch::optim::Optimizer& opt,
                   double clip) override {
    FcaLosses l = fca_step(c_.nets, opt, c_.batcher.batch(true, rows, n), c_.settings, clip);
    return {l.policy, {l.adversary}};
  }

 private:
  FamilyContext& c_;
};

}  // namespace

TrainSummary train_fca(const Settings& settings, const TrainRequest& req) {
  FamilyMethod m;
  m.tables = {"fca"};
  m.action_lags = [](const Settings&) { return 1; };
  m.adam = [](const Settings& s) {
    return torch::optim::AdamOptions(s.train.lr).betas({s.fca.beta1, 0.999});
  };
  m.objective = [](FamilyContext& c, nlohmann::json&) -> std::unique_ptr<Objective> {
    return std::make_unique<FcaObjective>(c);
  };
  return train_policy_family(settings, req, m);
}

}  // namespace cd
