// keyframe (Wen et al., "Keyframe-focused visual imitation learning"): bc-oh whose loss
// up-weights the samples where the expert's action changes. An action-prediction model (an
// MLP over the previous keyframe.actions recorded actions, 300 hidden units, LeakyReLU 0.2,
// as in the public code) is trained first on the training split; its error on a sample (APE,
// per action component) says how much the action departs from what the past actions predict.
// threshold mode: the top 10% of APE get weight 5, the rest 1; softmax mode: a softmax of
// APE / temperature over each batch. The validation loss (what picks the best epoch) is the
// unweighted bc loss, so the epochs of every method are chosen by the same measure.
#include <algorithm>
#include <cmath>
#include <optional>

#include "core/rng.hpp"
#include "methods/policy_family.hpp"

namespace cd {

namespace {

constexpr uint64_t kApeStream = 0x4ef1;

// The action-prediction model's data: previous actions (n x L*A) and a_t (n x A) of a split.
struct ApeData {
  torch::Tensor x, y;
};

ApeData ape_data(const Dataset& data, const std::vector<SampleRef>& samples, int L) {
  const int A = data.action_dim();  // as learned (model.pedals)
  const int64_t n = static_cast<int64_t>(samples.size());
  ApeData d{torch::empty({n, L * A}), torch::empty({n, A})};
  float* x = d.x.data_ptr<float>();
  float* y = d.y.data_ptr<float>();
  for (int64_t i = 0; i < n; ++i) {
    const int e = samples[i].episode, t = samples[i].t;
    data.action_at(e, t, y + i * A);
    for (int l = 1; l <= L; ++l) data.action_at(e, t - l, x + (i * L + l - 1) * A);
  }
  return d;
}

class ApeObjective : public Objective {
 public:
  ApeObjective(torch::nn::Sequential& net, const ApeData& train, const ApeData& val)
      : net_(net), train_(train), val_(val) {}
  void set_training(bool on) override { net_->train(on); }
  BatchLoss loss(bool training, const uint32_t* rows, int64_t n) override {
    const ApeData& d = training ? train_ : val_;
    torch::Tensor idx = torch::from_blob(const_cast<uint32_t*>(rows), {n}, torch::kInt32)
                            .to(torch::kInt64);
    return {torch::mse_loss(net_->forward(d.x.index_select(0, idx)), d.y.index_select(0, idx)),
            {}};
  }

 private:
  torch::nn::Sequential& net_;
  const ApeData& train_;
  const ApeData& val_;
};

}  // namespace

torch::Tensor keyframe_threshold_weights(const torch::Tensor& ape, double top_fraction,
                                         double top_weight) {
  const int64_t n = ape.size(0);
  const int64_t top = std::min<int64_t>(n, static_cast<int64_t>(std::ceil(top_fraction * n)));
  torch::Tensor w = torch::ones_like(ape);
  if (top == 0) return w;
  // Per component: the top-th largest error is the threshold.
  torch::Tensor thr = std::get<0>(ape.topk(top, 0, true, true)).select(0, top - 1);
  return torch::where(ape >= thr.unsqueeze(0), torch::full_like(ape, top_weight), w);
}

torch::Tensor keyframe_softmax_weights(const torch::Tensor& ape, double temperature) {
  return static_cast<double>(ape.size(0)) * torch::softmax(ape / temperature, 0);
}

KeyframeWeights::KeyframeWeights(FamilyContext& c, nlohmann::json& record) : s_(c.settings) {
  const KeyframeSettings& k = s_.keyframe;
  const Dataset& data = c.data;
  const int A = data.action_dim(), L = k.actions;
  const ApeData train = ape_data(data, data.train(), L), val = ape_data(data, data.val(), L);

  // Trained on the CPU from its own stream of train.seed, whatever the policy's device.
  torch::manual_seed(derive_seed(s_.train.seed, kApeStream));
  const auto leaky = torch::nn::LeakyReLUOptions().negative_slope(0.2);
  torch::nn::Sequential net(torch::nn::Linear(L * A, k.hidden), torch::nn::LeakyReLU(leaky),
                            torch::nn::Linear(k.hidden, k.hidden), torch::nn::LeakyReLU(leaky),
                            torch::nn::Linear(k.hidden, A));
  torch::optim::Adam opt(net->parameters(), torch::optim::AdamOptions(k.lr));
  ApeObjective objective(net, train, val);
  LoopPlan plan;
  plan.first_epoch = 1;
  plan.last_epoch = k.epochs;
  plan.batch_size = k.batch_size;
  plan.train_size = static_cast<size_t>(train.x.size(0));
  plan.val_size = static_cast<size_t>(val.x.size(0));
  plan.shuffle_seed = derive_seed(s_.train.seed, kApeStream + 1);
  LoopState state{false, 0, 0, 0, k.lr};
  double last_train = 0;
  std::optional<double> last_val;
  train_epochs(objective, opt, plan, state, [&](const EpochResult& r) {
    last_train = r.train_loss;
    last_val = r.val_loss;
  });

  {
    torch::NoGradGuard no_grad;
    net->eval();
    ape_ = (net->forward(train.x) - train.y).abs();
  }
  if (k.mode == "threshold") weights_ = keyframe_threshold_weights(ape_, k.top_fraction, k.top_weight);
  ape_ = ape_.to(c.device);
  if (weights_.defined()) weights_ = weights_.to(c.device);

  auto per_component = [&](const torch::Tensor& t) {
    torch::Tensor v = t.to(torch::kCPU).to(torch::kFloat64).contiguous();
    return std::vector<double>(v.data_ptr<double>(), v.data_ptr<double>() + v.numel());
  };
  record = {{"ape_model",
             {{"epochs", k.epochs},
              {"train_mse", last_train},
              {"val_mse", last_val ? nlohmann::json(*last_val) : nlohmann::json(nullptr)}}},
            {"mode", k.mode},
            {"mean_ape", per_component(ape_.mean(0))}};
  if (weights_.defined()) {
    // The smallest up-weighted error per component.
    torch::Tensor up = torch::where(weights_ > 1, ape_, torch::full_like(ape_, INFINITY));
    record["thresholds"] = per_component(std::get<0>(up.min(0)));
    record["weighted_share"] = per_component((weights_ > 1).to(torch::kFloat64).mean(0));
  }
}

torch::Tensor KeyframeWeights::of(const PolicyBatch& b) const {
  if (weights_.defined()) return weights_.index_select(0, b.rows);
  return keyframe_softmax_weights(ape_.index_select(0, b.rows), s_.keyframe.temperature);
}

namespace {

class KeyframeObjective : public Objective {
 public:
  KeyframeObjective(FamilyContext& c, nlohmann::json& record) : c_(c), weights_(c, record) {}
  void set_training(bool on) override { c_.nets.set_training(on); }
  BatchLoss loss(bool training, const uint32_t* rows, int64_t n) override {
    PolicyBatch b = c_.batcher.batch(training, rows, n);
    PolicyOutput out = c_.nets.policy->forward(b.image, b.speed_in, b.command, true);
    torch::Tensor w = sample_weights(b, training ? weights_.of(b) : torch::Tensor());
    return {policy_loss(c_.settings, out, b.action, b.speed_label, w), {}};
  }

 private:
  FamilyContext& c_;
  KeyframeWeights weights_;
};

}  // namespace

TrainSummary train_keyframe(const Settings& settings, const TrainRequest& req) {
  FamilyMethod m;
  m.tables = {"keyframe"};
  m.action_lags = [](const Settings& s) { return s.keyframe.actions; };
  m.objective = [](FamilyContext& c, nlohmann::json& record) -> std::unique_ptr<Objective> {
    return std::make_unique<KeyframeObjective>(c, record);
  };
  return train_policy_family(settings, req, m);
}

}  // namespace cd
