// bc-so and bc-oh (seed 001's baselines): behaviour cloning of the expert's recorded actions
// from the current frame (bc-so) or a stack of real history frames (bc-oh), resumable.
//
// Loss: L(action) + model.speed_loss_weight * L(speed head), L = L1 or L2 (train.loss); Adam
// with the plateau rule of train/loop.hpp (train.lr_patience, lr_decay, lr_min). The weights
// come from train.seed, shuffling and dropout of epoch n from (seed, n), so a run resumed after
// epoch n gives the same bytes as one that never stopped (with the same train.threads).
// The trainer, run folder and agent are the family's (methods/policy_family.hpp).
#include "methods/policy_family.hpp"

namespace cd {

namespace {

class BcObjective : public Objective {
 public:
  explicit BcObjective(FamilyContext& c) : c_(c) {}
  void set_training(bool on) override { c_.nets.set_training(on); }
  BatchLoss loss(bool training, const uint32_t* rows, int64_t n) override {
    PolicyBatch b = c_.batcher.batch(training, rows, n);
    PolicyOutput out = c_.nets.policy->forward(b.image, b.speed_in, b.command, true);
    return {policy_loss(c_.settings, out, b.action, b.speed_label, sample_weights(b)), {}};
  }

 private:
  FamilyContext& c_;
};

}  // namespace

FamilyMethod bc_family_method() {
  FamilyMethod m;
  m.objective = [](FamilyContext& c, nlohmann::json&) -> std::unique_ptr<Objective> {
    return std::make_unique<BcObjective>(c);
  };
  return m;
}

TrainSummary train_bc(const Settings& settings, const TrainRequest& req) {
  return train_policy_family(settings, req, bc_family_method());
}

void bc_so_settings(Settings& s) {
  s.model.history = 1;
  s.model.history_stride = 1;
}

}  // namespace cd
