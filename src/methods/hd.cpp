// hd: history dropout. bc-oh whose samples lose their past frames with probability hd.p
// during training (ChauffeurNet drops its past-motion input with probability 0.5; none of the
// copycat papers publishes its HD baseline, so this is our reading, said in the config): the
// policy must drive from the current frame alone half the time, so it cannot rely on the
// history to copy its past motion. Validation and the agent see full histories.
#include "core/error.hpp"
#include "methods/policy_family.hpp"

namespace cd {

torch::Tensor history_dropout(torch::Tensor& image, int frame_channels, double p) {
  const int64_t n = image.size(0), past = image.size(1) - frame_channels;
  torch::Tensor keep = (torch::rand({n}) >= p).to(torch::kFloat32).to(image.device());
  if (past > 0) {
    torch::Tensor history = image.narrow(1, 0, past);
    history.mul_(keep.view({n, 1, 1, 1}));
  }
  return keep;
}

namespace {

class HdObjective : public Objective {
 public:
  explicit HdObjective(FamilyContext& c) : c_(c) {}
  void set_training(bool on) override { c_.nets.set_training(on); }
  BatchLoss loss(bool training, const uint32_t* rows, int64_t n) override {
    PolicyBatch b = c_.batcher.batch(training, rows, n);
    if (training) history_dropout(b.image, c_.data.episodes().channels, c_.settings.hd.p);
    PolicyOutput out = c_.nets.policy->forward(b.image, b.speed_in, b.command, true);
    return {policy_loss(c_.settings, out, b.action, b.speed_label, sample_weights(b)), {}};
  }

 private:
  FamilyContext& c_;
};

}  // namespace

TrainSummary train_hd(const Settings& settings, const TrainRequest& req) {
  if (settings.model.history < 2)
    throw ConfigError("hd drops the frame history: it needs model.history >= 2");
  FamilyMethod m;
  m.tables = {"hd"};
  m.objective = [](FamilyContext& c, nlohmann::json&) -> std::unique_ptr<Objective> {
    return std::make_unique<HdObjective>(c);
  };
  return train_policy_family(settings, req, m);
}

}  // namespace cd
