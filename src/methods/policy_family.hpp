#pragma once
// What bc-so, bc-oh and seed 001's methods (residual, fca, keyframe, hd, dagger) share: they
// all learn actions from (frame history, action sequence) samples of a Dataset, and none of
// them knows what the frames show or how many action components there are (SPEC section 3,
// "one implementation per method, any domain"). Here: batches of those samples, the loss of
// an action and its speed head, the one trainer (run folder, resume, commit; runs/checkpoint.hpp)
// that every method plugs its Objective into, and the agent that drives with the result.
// Each method's own part is in methods/<name>.cpp.
//
// This header includes torch: include it only from the methods' .cpp files.
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "app/settings.hpp"
#include "datasets/dataset.hpp"
#include "methods/method.hpp"
#include "nn/policy_nets.hpp"
#include "train/loop.hpp"
#include "train/request.hpp"

namespace cd {

// A batch of samples on the training device.
struct PolicyBatch {
  int64_t n = 0;
  torch::Tensor image;        // n x K*C x H x W, oldest frame first
  torch::Tensor speed_in;     // n x 1 (zeros unless model.speed_input)
  torch::Tensor command;      // n, int64
  torch::Tensor action;       // n x A: a_t
  torch::Tensor speed_label;  // n x 1
  torch::Tensor previous;     // n x L x A: a_{t-1} .. a_{t-L}; undefined when L = 0
  torch::Tensor rows;         // n, int64: the samples' indices in their split
  // n: the samples' situation weights (train.situation_weights) in a training batch; undefined
  // when they are off and in validation batches (the validation loss stays unweighted).
  torch::Tensor weight;
  // The current frame: the last C planes of image.
  torch::Tensor current(int frame_channels) const;
};

// Fills batches of a Dataset's splits (frames unpacked over torch's threads; each sample
// writes its own rows, so the result does not depend on the thread count). On CUDA the host
// buffers are pinned and copied without blocking, in two sets used in turn: batch n+1 is filled
// while the GPU still copies and runs batch n (the loop reads a batch's loss one batch late).
class PolicyBatcher {
 public:
  // train_weights: one weight per training sample (train.situation_weights), or empty.
  PolicyBatcher(const Dataset& data, int batch_size, const torch::Device& device,
                const std::vector<float>& train_weights = {});
  PolicyBatch batch(bool training, const uint32_t* rows, int64_t n);
  const Dataset& data() const { return data_; }

 private:
  struct Staging {
    torch::Tensor image, speed_in, command, action, speed_label, previous, rows;
  };
  const Dataset& data_;
  torch::Device device_;
  bool cuda_ = false;
  Staging staging_[2];  // host buffers; the CPU uses the first alone
  int next_ = 0;
  torch::Tensor train_weights_;  // N_train on the device, or undefined
};

// A method's own per-sample weights (n, or n x A; undefined for none) times the batch's
// situation weights: what its action loss is weighted with.
torch::Tensor sample_weights(const PolicyBatch& batch, const torch::Tensor& own = {});

// The validated recipe's "auto" values resolved for data of `domain` (model.pedals: "signed"
// for driving through a throttle_brake head, else "two"; train.situation_weights: "balanced"
// for driving data that records the situations' causes, else "none"). Explicit values stay as
// given. Runs record the resolved settings.
Settings resolve_recipe(Settings s, const std::string& domain, bool situation_causes);

// train.situation_weights = "balanced": the weight of each training sample of `data`
// (datasets/situation.hpp); empty for "none". Throws ConfigError for data without the causes.
std::vector<float> situation_weights(const Settings& s, const Dataset& data);

// Mean L1 or L2 (train.loss) of pred - target; with `weights` (n), each sample's mean over
// its components is weighted, and the sum is divided by n.
torch::Tensor action_loss(const std::string& kind, const torch::Tensor& pred,
                          const torch::Tensor& target, const torch::Tensor& weights = {});

// What a CILRS-style module is trained on: L(action) + model.speed_loss_weight * L(speed head)
// (seed 001 eq. 4 with alpha = 1 / (1 + weight), up to a constant factor that Adam ignores).
torch::Tensor policy_loss(const Settings& s, const PolicyOutput& out, const torch::Tensor& target,
                          const torch::Tensor& speed_label, const torch::Tensor& weights = {});

// What a method's Objective is built from.
struct FamilyContext {
  const Settings& settings;
  const Dataset& data;
  PolicyNets& nets;
  PolicyBatcher& batcher;
  torch::Device device;
  bool quiet = false;
};

// A method of the family, as the trainer needs it.
struct FamilyMethod {
  // Previous actions each sample carries (a_{t-1}..a_{t-L}); samples start at t >= L.
  std::function<int(const Settings&)> action_lags = [](const Settings&) { return 0; };
  // The method's objective; may do work first (keyframe's weights) and say what it found in
  // `record` (kept in checkpoint.json as method_record).
  std::function<std::unique_ptr<Objective>(FamilyContext&, nlohmann::json& record)> objective;
  // Adam's options (fca: its betas); default Adam(train.lr).
  std::function<torch::optim::AdamOptions(const Settings&)> adam;
  // Settings tables a resumed run must share besides [model] and [train].
  std::vector<std::string> tables;
};

// Where a family run trains from (dagger: several folders and a warm start).
struct FamilyData {
  std::vector<std::string> dirs;  // collect folders, concatenated in this order
  std::string init_weights;       // a file of the same networks to start from; "" = fresh
};

// bc's objective (bc-so, bc-oh, and the policy dagger aggregates data for).
FamilyMethod bc_family_method();

// Trains `method` into request.out_dir (resumable; same seed, same bytes; a folder of another
// run is refused). `data` defaults to request.data_dir.
TrainSummary train_policy_family(const Settings& settings, const TrainRequest& request,
                                 const FamilyMethod& method, const FamilyData& data = {});

// The agent of every family method: its networks from the run folder, driving with their
// action (or a target speed through [control]'s PID).
std::unique_ptr<Agent> load_policy_family_agent(const std::string& method, const std::string& dir,
                                                const Settings& settings, const World* world);

// The layout of a dataset's networks for `method` with `settings`.
PolicyNetsLayout layout_for(const std::string& method, const Settings& s, const EpisodeSet& eps);

}  // namespace cd

namespace cd {

// ---- the methods' own pieces, pure functions of tensors (tested on hand-computed batches) ----

// hd: each sample's past frames (all but the last frame_channels planes) are zeroed with
// probability p (torch's generator; the loop seeds it per epoch). Returns the mask (n, 1 =
// kept) and changes image in place.
torch::Tensor history_dropout(torch::Tensor& image, int frame_channels, double p);

// residual: the memory module's targets for memory_target residual (a_t - a_{t-i}, i = 1..heads,
// concatenated), action (a_t) or previous (a_{t-1}). previous: n x L x A, a_{t-1} first.
torch::Tensor memory_targets(const std::string& memory_target, const torch::Tensor& action,
                             const torch::Tensor& previous, int heads);

// keyframe: weights from action-prediction errors ape (n x A, one column per component).
// threshold: per component, the top_fraction largest errors get top_weight, the rest 1
// (ceil(top_fraction * n) samples; ties at the threshold all count as top).
torch::Tensor keyframe_threshold_weights(const torch::Tensor& ape, double top_fraction,
                                         double top_weight);
// softmax: per component, n * softmax(ape / temperature) over the n samples (mean weight 1).
torch::Tensor keyframe_softmax_weights(const torch::Tensor& ape, double temperature);

// keyframe's sample weights for a dataset's training split: the action-prediction model over
// the previous keyframe.actions actions, trained first (seeded), then its error per training
// sample. `record` gets the model's losses and the thresholds.
class KeyframeWeights {
 public:
  KeyframeWeights(FamilyContext& context, nlohmann::json& record);
  // The weights of training rows (n x A), for the batch (softmax mode normalises over it).
  torch::Tensor of(const PolicyBatch& batch) const;

 private:
  const Settings& s_;
  torch::Tensor ape_;      // N_train x A
  torch::Tensor weights_;  // threshold mode: N_train x A
};

// fca: the adversary's loss, the squared error of D([embedding, a_t]) against a_{t-1} summed
// over action components, mean over the batch.
torch::Tensor fca_adversary_loss(torch::nn::Sequential& adversary, const torch::Tensor& embedding,
                                 const torch::Tensor& action, const torch::Tensor& previous_action);

// fca's two alternating steps on one batch (D, then E + F against the updated D), with one
// optimiser over nets.parameters(). Returns the policy loss and D's loss before its step.
struct FcaLosses {
  torch::Tensor policy, adversary;
};
FcaLosses fca_step(PolicyNets& nets, torch::optim::Optimizer& opt, const PolicyBatch& batch,
                   const Settings& settings, double clip_grad_norm);

// residual's two losses on a batch: the memory module's (its target and speed head) and the
// acting part's (the policy module on the detached memory feature, or the learned controller;
// zero for the residual controller). `weights`: per-sample weights of the acting loss.
struct ResidualLosses {
  torch::Tensor memory, act;
};
ResidualLosses residual_losses(PolicyNets& nets, const PolicyBatch& batch, const Settings& settings,
                               int frame_channels, const torch::Tensor& weights = {});

// Sets the gradients of `params` to undefined, so Adam leaves them as they are in the next step
// (two alternating steps with one optimiser behave as two optimisers).
void clear_grads(const std::vector<torch::Tensor>& params);

}  // namespace cd
