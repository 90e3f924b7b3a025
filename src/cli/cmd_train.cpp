#include <cstdio>
#include <memory>

#include "cli/commands.hpp"
#include "cli/common.hpp"
#include "core/error.hpp"
#include "core/progress.hpp"
#include "learn/checkpoint.hpp"
#include "learn/cim.hpp"
#include "learn/dim_trainer.hpp"
#include "learn/methods.hpp"
#include "learn/trainer.hpp"

namespace cd::cli {

namespace {

struct TrainArgs {
  std::string config, method, data, out, device, init, vae;
  int epochs = 0, threads = 0;
  long max_samples = -1;
  int64_t seed = -1;
};

}  // namespace

void add_train(CLI::App& app) {
  auto args = std::make_shared<TrainArgs>();
  CLI::App* sub = app.add_subcommand(
      "train", "train a policy (bc-so, bc-oh, dim, rip, cim, cim-mlp, cim-entangled) on recorded "
               "expert episodes");
  sub->add_option("--config,-c", args->config, "TOML config (default: built-in quickstart)");
  sub->add_option("--method,-m", args->method,
                  "bc-so | bc-oh | dim | rip | cim | cim-mlp | cim-entangled")
      ->required();
  sub->add_option("--data,-d", args->data, "data folder of `causaldrive collect` (collect.out)");
  sub->add_option("--out,-o", args->out,
                  "checkpoint folder (train.out); a rerun resumes from its last finished epoch");
  sub->add_option("--epochs", args->epochs, "epochs in total (train.epochs)")
      ->check(CLI::PositiveNumber);
  sub->add_option("--max-samples", args->max_samples,
                  "keep a seeded subset of this many samples, 0 = all (train.max_samples)")
      ->check(CLI::NonNegativeNumber);
  sub->add_option("--seed", args->seed, "seed of weights, split and shuffling (train.seed)")
      ->check(CLI::NonNegativeNumber);
  sub->add_option("--threads", args->threads, "torch threads (train.threads)")
      ->check(CLI::PositiveNumber);
  sub->add_option("--device", args->device, "cpu | cuda | auto (train.device)")
      ->check(CLI::IsMember({"cpu", "cuda", "auto"}));
  sub->add_option("--init", args->init,
                  "cim family: a finished run whose VAE and causes are kept and whose speed "
                  "predictor is fine-tuned on --data (few-shot adaptation)");
  sub->add_option("--vae", args->vae,
                  "cim family: reuse the VAE of this run folder instead of training one");
  sub->callback([args] {
    Settings s = settings_from(args->config);
    if (args->epochs > 0) s.train.epochs = args->epochs;
    if (args->max_samples >= 0) s.train.max_samples = args->max_samples;
    if (args->seed >= 0) s.train.seed = static_cast<uint64_t>(args->seed);
    if (args->threads > 0) s.train.threads = args->threads;
    if (!args->device.empty()) s.train.device = args->device;
    if (!args->out.empty()) s.train.out = args->out;
    TrainRequest req;
    req.method = args->method;
    req.data_dir = args->data.empty() ? s.collect.out : args->data;
    req.out_dir = s.train.out;
    req.init = args->init;
    req.vae_from = args->vae;
    check_train_method(req.method);
    const bool cim = req.method.rfind("cim", 0) == 0;
    if (!cim && (!req.init.empty() || !req.vae_from.empty()))
      throw ConfigError("--init and --vae apply to the cim family only (cim, cim-mlp, "
                        "cim-entangled), not to '" + req.method + "'");
    if (cim)
      print_train_summary(train_cim(s, req));
    else if (req.method == "dim" || req.method == "rip")
      print_train_summary(train_dim(s, req));
    else
      print_train_summary(train_policy(s, req));
  });
}

}  // namespace cd::cli
