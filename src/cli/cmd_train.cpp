#include <cstdio>
#include <memory>

#include "cli/commands.hpp"
#include "cli/common.hpp"
#include "core/error.hpp"
#include "core/progress.hpp"
#include "methods/method.hpp"

namespace cd::cli {

namespace {

struct TrainArgs {
  std::string config, method, data, out, device, precision, init, vae;
  int epochs = 0, threads = 0;
  long max_samples = -1;
  int64_t seed = -1;
};

}  // namespace

void add_train(CLI::App& app) {
  auto args = std::make_shared<TrainArgs>();
  std::string names, help;
  for (const MethodSpec& m : methods()) {
    if (!m.train) continue;
    names += (names.empty() ? "" : " | ") + std::string(m.name);
    help += "\n    " + std::string(m.name) + ": " + m.help;
  }
  CLI::App* sub = app.add_subcommand(
      "train", "train a method (" + names + ") on recorded expert episodes");
  sub->add_option("--config,-c", args->config, "TOML config (default: built-in quickstart)");
  sub->add_option("--method,-m", args->method, names + help)->required();
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
  sub->add_option("--device", args->device, "auto | cpu | cuda (train.device)")
      ->check(CLI::IsMember({"auto", "cpu", "cuda"}));
  sub->add_option("--precision", args->precision,
                  "fp32 | bf16: bf16 autocast of the forward passes, CUDA only (train.precision)")
      ->check(CLI::IsMember({"fp32", "bf16"}));
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
    if (!args->precision.empty()) s.train.precision = args->precision;
    if (!args->out.empty()) s.train.out = args->out;
    TrainRequest req;
    req.method = args->method;
    req.data_dir = args->data.empty() ? s.collect.out : args->data;
    req.out_dir = s.train.out;
    req.init = args->init;
    req.vae_from = args->vae;
    print_train_summary(train_method(s, req));
  });
}

}  // namespace cd::cli
