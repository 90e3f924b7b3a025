// `causaldrive bench`: the command line of the benchmarks (bench/throughput, mujoco/bench,
// bench/train_bench hold their logic).
#include <cstdio>
#include <memory>

#include <nlohmann/json.hpp>

#include "app/build_info.hpp"
#include "bench/throughput.hpp"
#include "bench/train_bench.hpp"
#include "cli/commands.hpp"
#include "cli/common.hpp"
#include "core/error.hpp"
#include "mujoco/bench.hpp"

namespace cd::cli {

void add_bench(CLI::App& app) {
  CLI::App* bench = app.add_subcommand("bench", "throughput benchmarks");
  bench->require_subcommand(1);
  auto config = std::make_shared<std::string>();
  auto steps = std::make_shared<long>(3000);
  auto slices = std::make_shared<int>(6);
  auto json = std::make_shared<bool>(false);
  CLI::App* world = bench->add_subcommand(
      "world", "bare SUMO stepping against the full loop, interleaved over task slices");
  world->add_option("--config,-c", *config, "TOML config (default: built-in quickstart)");
  world->add_option("--steps", *steps, "steps measured for each of the two loops, in all")
      ->check(CLI::PositiveNumber);
  world->add_option("--slices", *slices,
                    "tasks the steps are split over; the loops alternate slice by slice")
      ->check(CLI::PositiveNumber);
  world->add_flag("--json", *json, "print one JSON object");
  auto view = std::make_shared<std::string>("bev");
  world->add_option("--view", *view,
                    "bev, or camera: also time the front camera's scene and render ([sense.camera]) "
                    "against the BEV's render, and give the camera loop's steps/s")
      ->check(CLI::IsMember({"bev", "camera"}));
  world->callback([=] { bench_world(settings_from(*config), *steps, *slices, *json, *view); });

  auto agent = std::make_shared<std::string>();
  auto checkpoint = std::make_shared<std::string>();
  auto suite = std::make_shared<std::string>("town-a-regular");
  auto episodes = std::make_shared<int>(5);
  CLI::App* ev = bench->add_subcommand(
      "eval", "closed-loop steps/s of an agent, inference included, against the expert "
              "(interleaved episode by episode)");
  ev->add_option("--config,-c", *config, "TOML config (default: built-in quickstart)");
  ev->add_option("--agent", *agent, "any agent name (see `eval --help`)")->required();
  ev->add_option("--checkpoint", *checkpoint, "training output folder of a learned agent");
  ev->add_option("--suite", *suite, "suite whose first tasks are driven");
  ev->add_option("--episodes", *episodes, "episodes per agent")->check(CLI::PositiveNumber);
  ev->add_flag("--json", *json, "print one JSON object");
  auto profile = std::make_shared<bool>(false);
  ev->add_flag("--profile", *profile,
               "also say where a step's time goes: the agent's sensor (BEV and history), its "
               "act (inference; with --workers and batched inference, the wait for the "
               "inference process, whose own time per observation is shown apart), the "
               "world's step, the scorer, the rest");
  auto workers = std::make_shared<int>(0);
  auto eval_rounds = std::make_shared<int>(3);
  auto baseline = std::make_shared<int>(2);
  ev->add_option("--workers", *workers,
                 "0 (default): one process, episode by episode; N: whole evaluations at N "
                 "workers as `eval` runs them (eval.batch as configured), each round the agent, "
                 "the expert and the baseline");
  ev->add_option("--rounds", *eval_rounds, "with --workers: rounds")->check(CLI::PositiveNumber);
  ev->add_option("--baseline-workers", *baseline,
                 "with --workers: the agent with eval.batch = \"off\" at this many workers "
                 "(today's evaluation) in each round; 0 leaves it out");
  ev->callback([=] {
    if (*workers > 0) {
      bench_eval_workers(settings_from(*config), *agent, *checkpoint, *suite, *episodes,
                         *workers, *eval_rounds, *baseline, *json, *profile);
      return;
    }
    bench_eval(settings_from(*config), *agent, *checkpoint, *suite, *episodes, *json, *profile);
  });

  auto slot_list = std::make_shared<std::vector<int>>(std::vector<int>{1, 2, 4, 8, 16});
  auto rounds = std::make_shared<int>(20);
  auto threads = std::make_shared<int>(1);
  CLI::App* inf = bench->add_subcommand(
      "infer", "a learned agent's inference alone: one observation at a time against fixed "
               "batches (interleaved)");
  inf->add_option("--checkpoint", *checkpoint, "training output folder of a policy-family run")
      ->required();
  inf->add_option("--slots", *slot_list, "batch sizes compared with one row at a time")
      ->delimiter(',');
  inf->add_option("--rounds", *rounds, "interleaved rounds")->check(CLI::PositiveNumber);
  inf->add_option("--threads", *threads, "torch threads (closed loop: 1)")
      ->check(CLI::PositiveNumber);
  inf->add_flag("--json", *json, "print one JSON object");
  inf->callback([=] { bench_infer(*checkpoint, *slot_list, *rounds, *threads, *json); });

  auto env_args = std::make_shared<mj::EnvBenchArgs>();
  CLI::App* en = bench->add_subcommand(
      "env", "MuJoCo-Image: bare physics steps/s against physics + rendering, per frame size, "
             "interleaved in one run");
  en->add_option("--env", env_args->env, "halfcheetah, hopper, ant, reacher or humanoid")
      ->required();
  en->add_option("--size", env_args->sizes,
                 "frame width and height; several (--size 32,64,128) show how rendering scales")
      ->delimiter(',')
      ->check(CLI::Range(1, 4096));
  en->add_option("--steps", env_args->steps, "steps measured for each loop, in all")
      ->check(CLI::PositiveNumber);
  en->add_option("--slices", env_args->slices, "the loops alternate slice by slice")
      ->check(CLI::PositiveNumber);
  en->add_option("--expert-steps", env_args->expert_steps,
                 "also time this many steps per slice of physics + render (first size) + the "
                 "planner expert")
      ->check(CLI::NonNegativeNumber);
  en->add_option("--seed", env_args->seed, "seed of the start states and actions");
  en->add_flag("--json", env_args->json, "print one JSON object");
  en->callback([=] { mj::bench_env(*env_args); });

  auto ex_env = std::make_shared<std::string>();
  auto ex_opts = std::make_shared<mj::PlannerOptions>();
  auto ex_steps = std::make_shared<int>(0);
  auto ex_seed = std::make_shared<uint64_t>(0);
  CLI::App* ex = bench->add_subcommand(
      "expert", "MuJoCo-Image: the planner expert's return and seconds per step in closed loop");
  ex->add_option("--env", *ex_env, "halfcheetah, hopper, ant, reacher or humanoid")->required();
  ex->add_option("--steps", *ex_steps, "steps (default: the env's episode limit)")
      ->check(CLI::NonNegativeNumber);
  ex->add_option("--seed", *ex_seed, "episode seed (the reset noise; the planner's is derived)");
  ex->add_option("--samples", ex_opts->samples, "rollouts per iteration (default per env)");
  ex->add_option("--horizon", ex_opts->horizon, "rollout length in steps (default per env)");
  ex->add_option("--iterations", ex_opts->iterations, "refinements per step (default per env)");
  ex->add_option("--sigma", ex_opts->sigma, "noise, fraction of the half ctrlrange");
  ex->add_option("--temperature", ex_opts->temperature, "weight temperature (of the range)");
  ex->add_option("--smoothing", ex_opts->smoothing, "noise time correlation in [0, 1)");
  ex->add_option("--terminal-steps", ex_opts->terminal_steps,
                 "terminal value: the last reward counted this many more times");
  ex->add_flag("--json", *json, "print one JSON object");
  ex->callback([=] { mj::bench_expert(*ex_env, *ex_opts, *ex_steps, *ex_seed, *json); });

  auto tr = std::make_shared<TrainBenchOptions>();
  CLI::App* train = bench->add_subcommand(
      "train", "training steps of a policy network alone, on random inputs already on the "
               "device (samples/s; scripts/gpu_peer.py is its PyTorch-Python peer)");
  train->add_option("--method", tr->method, "a method of the policy family (default bc-oh)");
  train->add_option("--backbone", tr->backbone, "small | resnet34 (model.backbone)")
      ->check(CLI::IsMember({"small", "resnet34"}));
  train->add_option("--device", tr->device, "auto | cpu | cuda")
      ->check(CLI::IsMember({"auto", "cpu", "cuda"}));
  train->add_option("--precision", tr->precision, "fp32 | bf16 (CUDA)")
      ->check(CLI::IsMember({"fp32", "bf16"}));
  train->add_option("--batch", tr->batch, "samples per step (default 128)")
      ->check(CLI::PositiveNumber);
  train->add_option("--steps", tr->steps, "timed steps (default 50)")->check(CLI::PositiveNumber);
  train->add_option("--warmup", tr->warmup, "untimed steps first (default 5)")
      ->check(CLI::NonNegativeNumber);
  train->add_option("--threads", tr->threads, "torch threads (default: all cores)")
      ->check(CLI::NonNegativeNumber);
  train->add_option("--size", tr->height, "frame height and width in pixels (default 64)")
      ->check(CLI::PositiveNumber);
  train->add_option("--huge-pages", tr->huge_pages,
                    "large CPU tensors on huge pages: on (default), off, or both (alternating, "
                    "with their ratio)")
      ->check(CLI::IsMember({"on", "off", "both"}));
  train->add_flag("--json", *json, "print one JSON object");
  train->callback([=] {
    TrainBenchOptions o = *tr;
    o.width = o.height;
    const nlohmann::json r = bench_train_step(o);
    if (*json) {
      nlohmann::json j = r;
      j["build"] = build_components();
      std::printf("%s\n", j.dump().c_str());
      return;
    }
    std::printf("%s %s on %s (%s), batch %d: %.0f samples/s over %d steps (%ld parameters)\n",
                o.method.c_str(), o.backbone.c_str(), r["device"].get<std::string>().c_str(),
                r["precision"].get<std::string>().c_str(), o.batch,
                r["samples_per_s"].get<double>(), o.steps, r["parameters"].get<long>());
    if (r["huge_pages"].is_object())
      std::printf("huge pages: %.0f samples/s off, %.0f on (ratio %.2f)\n",
                  r["huge_pages"]["off_samples_per_s"].get<double>(),
                  r["huge_pages"]["on_samples_per_s"].get<double>(),
                  r["huge_pages"]["ratio"].get<double>());
  });
}

}  // namespace cd::cli
