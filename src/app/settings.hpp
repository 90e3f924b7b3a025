#pragma once
// Every setting of a run, read from a TOML config (configs/quickstart.toml shows them all with
// their defaults). Unknown keys and out-of-range values are errors naming file and key. Each
// area owns its part (world/world_settings.hpp, control/pid.hpp, nn/model_settings.hpp,
// sense/bev.hpp); this file composes them and keeps the one list of keys (settings.cpp).
#include <cstdint>
#include <string>

#include <nlohmann/json_fwd.hpp>

#include "control/pid.hpp"
#include "expert/expert_settings.hpp"
#include "methods/method_settings.hpp"
#include "mujoco/mujoco_settings.hpp"
#include "nn/model_settings.hpp"
#include "sense/bev.hpp"
#include "sense/sensor_shift.hpp"
#include "world/world_settings.hpp"

namespace cd {

struct NoiseSettings {
  bool enabled = false;
  double rate_per_s = 0.05;  // expected starts of a noise window per second
  double min_s = 0.5;        // window length range
  double max_s = 1.5;
  double steer = 0.3;        // ego.lateral = "free": steer offset drawn in [-steer, steer]
};

// The lateral augmentation of a free-steering ego's data (the seeds' multi-camera augmentation):
// a fraction of the frames rendered from the ego's pose shifted sideways by up to shift_m and
// rotated by up to rotate_rad (uniform), labelled with the steer that corrects it (the expert's
// path tracker from that pose); throttle and brake stay the expert's.
struct AugmentSettings {
  double fraction = 0;       // 0: off
  double shift_m = 1.0;
  double rotate_rad = 0.15;
  // "random": shift and rotation uniform within the bounds; "sides": CILRS's left and right
  // cameras, the pose (+shift_m, +rotate_rad) (left of the ego, looking left) or (-shift_m,
  // -rotate_rad), left or right by a coin; each labelled with the steer that corrects it.
  std::string cameras = "random";
};

struct CollectSettings {
  int episodes = 24;
  uint64_t seed = 0;
  int workers = 2;
  std::string out = "runs/quickstart/data";
  double min_route_m = 300;
  double max_route_m = 700;
  double max_episode_s = 0;  // 0: the benchmark timeout (route at 5 km/h + 20 s)
  // s the ego is held braked at the start of an episode while the expert's labels (it wants to
  // go) are recorded: the state eval's history prefill (eval.prefill_s) puts a policy in, a
  // still history on a free road, with the expert's answer. Those steps are marked as not the
  // expert's motion (noise mask 1). 0: the expert drives from the first step. The default, 1 s,
  // is the validated recipe's (configs/residual_paper.toml); 0 was the default before it.
  double hold_s = 1.0;
  NoiseSettings noise;
  AugmentSettings augment;
};

struct TrainSettings {
  int epochs = 8;
  int batch_size = 64;
  double lr = 2e-4;
  double weight_decay = 0;       // Adam's L2 penalty (seed 001 table 12: 0.03)
  std::string loss = "l1";       // l1 | l2
  double val_fraction = 0.1;     // of the episodes, held out for validation
  int lr_patience = 1;           // epochs without a better validation loss before a decay
  double lr_decay = 0.5;
  double lr_min = 1e-6;
  uint64_t seed = 0;
  int threads = 2;               // torch intra-op threads
  // CPU training: treat denormal floats (below ~1.2e-38) as zero in every training thread (x86
  // FTZ/DAZ). Denormal operands make OpenBLAS's sgemm ~25x slower on this project's machines.
  bool flush_denormals = false;
  std::string device = "auto";   // auto | cpu | cuda (train/request.hpp: resolve_device)
  // "bf16": the forward passes run under CUDA's bf16 autocast (the weights and the optimiser
  // stay float32); "fp32": plain float32. CUDA only.
  std::string precision = "fp32";
  // CUDA: deterministic algorithms only (cuDNN's and cuBLAS's too); the CPU path always is.
  bool cuda_deterministic = false;
  long max_samples = 0;          // 0: every sample of the data folder
  // Samples per epoch (0: one pass over the training split): fewer take a fresh seeded subset
  // each epoch, more take several shuffled passes, so that runs on folders of any size get the
  // same number of updates (the paper's fixed iteration count). Methods trained by train.epochs.
  long epoch_samples = 0;
  // Per-sample weights of the action losses (driving data): "none", or "balanced": each
  // training sample weighs N / (C n_c) for its situation class c (datasets/situation.hpp:
  // the rare transitions, starting and stopping, as much in all as cruising), at most
  // situation_weight_max, then scaled to a mean of 1 (coiltraine's balanced batches, as weights).
  // "auto" (the default, the validated recipe's): "balanced" on driving data, "none" on other
  // domains; a run records the value it resolved to (resolve_recipe, methods/policy_family.hpp).
  std::string situation_weights = "auto";
  double situation_weight_max = 10.0;
  std::string out = "runs/quickstart/train";
};

struct EvalSettings {
  std::string suite = "quickstart";  // a built-in suite name or a suite file
  int trials = 0;                    // 0: the suite's own number of trials
  int workers = 2;
  std::string out = "runs/quickstart/eval";
  // Where the agents' networks run: auto | cpu | cuda (resolved in each worker at its first
  // step). One frame per step: on the small networks the CPU is often as fast.
  std::string device = "auto";
  double prefill_s = 1.0;   // s the ego is held still while the agent's history fills
  double cs_speed = 8.0;    // m/s of the constant-speed baseline
  int max_attempts = 3;     // an episode whose worker or SUMO crashed is run again this often
  // Batched inference (inference/batched_inference.hpp): "on", one inference process serves
  // the policy networks of all the worlds (2 or more workers); "off", each world runs its own;
  // "auto" (the default), on where eval.device is cuda (one process holds the GPU), off on the
  // CPU, where it was not faster on the 2-core machine it was measured on (ARCHITECTURE.md).
  // On the CPU the bytes are the same either way (batch-invariant kernels, nn/kernels.hpp).
  std::string batch = "auto";
  // What the agents' sensor shows (the failure modes' "new sensor" condition): "clean", or
  // "shifted" with the perception noise of sensor_shift (sense/sensor_shift.hpp). The expert
  // and the ground truth never see the shift.
  std::string sensor = "clean";
  SensorShift sensor_shift;
  // The path a free-steering cim (cim, cim-mlp, cim-entangled) steers along: empty, its route
  // with the expert's path tracker; or the run folder of a dim or rip model, whose planned path
  // it steers along (pure pursuit) at the causal speed predictor's speed, as seed 000's
  // controller merges the imitative model's trajectory with the causal speed.
  std::string cim_path;
};

// Cause selection and the causal speed predictor (seed 000 sections 4.2, 5.4.3).
struct CimSettings {
  int lags = 3;                         // Granger lags
  double alpha = 0.01;                  // level of the Granger tests
  std::string correction = "bonferroni";  // none | bonferroni | bh
  int max_causes = 4;                   // at most this many selected (ranked by the rule); 0 = all
  // The selection rule (causal/cause_selection.hpp): "bivariate" (each latent's F test against
  // the speed, the correction, alpha), "conditional" (each latent tested given the lags of all
  // the others, the correction, alpha) or "partial_r2" (the share of the speed's remaining
  // variance a latent's lags explain in the bivariate test, at least min_partial_r2).
  std::string selection = "partial_r2";
  double min_partial_r2 = 0.01;
  // The latents a rule may pick: "all", or "active" (mean KL over the predictor's training
  // frames > 0.01 nats; a latent whose posterior is the prior is no factor of the scene, its
  // mean only wiggles). Every latent is still tested and recorded.
  std::string candidates = "all";
  int series_stride = 5;                // simulation steps between the samples of the series
  int history = 3;                      // last values of each variable the predictor sees
  int history_stride = 5;               // simulation steps between them (= series_stride)
  // A few-shot run (train --init RUN): the predictor is fine-tuned for this many Adam steps on
  // the train.max_samples labels drawn from every episode of the data, which are all the
  // labels it uses (no validation split; the last weights are kept).
  int fewshot_steps = 300;
  int encoder_units = 16;               // per-variable linear encoder of cim, cim-entangled
  int mlp_encoder_units = 8;            // per-variable encoder of cim-mlp (all latents)
  int hidden = 64;                      // width of the predictor MLP
  int epochs = 50;                      // speed predictor epochs
  int batch_size = 256;
  double lr = 1e-3;
};

struct Settings : WorldConfig {  // world, ego, bev
  Settings() = default;  // not an aggregate: Settings{} is the defaults
  std::string source = "(built-in defaults)";  // where they came from
  ExpertSettings expert;
  CollectSettings collect;
  ControlSettings control;
  ModelSettings model;
  TrainSettings train;
  EvalSettings eval;
  VaeSettings vae;
  CimSettings cim;
  DimSettings dim;
  ResidualSettings residual;
  FcaSettings fca;
  KeyframeSettings keyframe;
  HdSettings hd;
  DaggerSettings dagger;
  MujocoSettings mujoco;
};

Settings load_settings(const std::string& path);  // throws ConfigError
// `base` with the keys of a TOML text set over it (the Python module's settings dict, as
// `world.traffic = "dense"` lines); unknown keys and values out of range are ConfigErrors
// naming `where` and the key, as in a config file.
Settings override_settings(const Settings& base, const std::string& toml,
                           const std::string& where);
nlohmann::json settings_to_json(const Settings& s);
// The inverse of settings_to_json, for run records: same keys and ranges as a config; missing
// keys keep their defaults, except the keys whose default changed since records lacked them
// (collect.hold_s 0, model.pedals "two", train.situation_weights "none": the values of their
// time); DataError naming `where` and the key otherwise.
Settings settings_from_json(const nlohmann::json& j, const std::string& where);

}  // namespace cd
