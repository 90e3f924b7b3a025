#include <cstdio>
#include <map>

#include "cli/commands.hpp"
#include "core/build_parts.hpp"
#include "core/mpi.hpp"
#include "cli/common.hpp"
#include "collect/collect.hpp"
#include "core/error.hpp"
#include "mujoco/collect.hpp"
#include "mujoco/env_spec.hpp"
#include "mujoco/expert.hpp"

namespace cd::cli {

namespace {

struct CollectArgs {
  std::string config, out, png, town, traffic;
  int episodes = 0, workers = 0;
  int64_t seed = -1;
  bool noise = false;
  // MuJoCo-Image (--env)
  std::string env;
  int size = 0, max_steps = 0, planner_samples = 0, planner_horizon = 0, planner_iterations = 0;
  double planner_sigma = 0, planner_temperature = 0, planner_smoothing = -1;
};

// collect --env NAME: the MuJoCo-Image domain, with the [mujoco] settings of --config; the
// driving options do not apply.
void collect_mujoco(const CollectArgs& a) {
  for (const auto& [given, flag] : {std::pair{!a.town.empty(), "--town"},
                                    {!a.traffic.empty(), "--traffic"},
                                    {!a.png.empty(), "--png"}}) {
    if (given) throw ConfigError(std::string(flag) + " is a driving option; it does not apply with --env");
  }
  require_mujoco("collect --env");
  mj::env_spec(a.env);  // an unknown env: one line, before the config is read
  const Settings s = settings_from(a.config);
  const MujocoSettings& m = s.mujoco;
  mj::CollectOptions o;
  o.env = a.env;
  o.out = a.out;
  o.episodes = a.episodes > 0 ? a.episodes : m.episodes.of(a.env);
  o.workers = a.workers > 0 ? a.workers : m.workers;
  o.seed = a.seed >= 0 ? static_cast<uint64_t>(a.seed) : m.seed;
  o.width = o.height = a.size > 0 ? a.size : m.size;
  o.max_steps = a.max_steps > 0 ? a.max_steps : m.max_steps;
  o.noise = {a.noise || m.noise.enabled, m.noise.rate, m.noise.min_steps, m.noise.max_steps,
             m.noise.sigma};
  o.planner = mj::planner_options(m);  // the flags override the [mujoco] keys
  if (a.planner_samples > 0) o.planner.samples = a.planner_samples;
  if (a.planner_horizon > 0) o.planner.horizon = a.planner_horizon;
  if (a.planner_iterations > 0) o.planner.iterations = a.planner_iterations;
  if (a.planner_sigma > 0) o.planner.sigma = a.planner_sigma;
  if (a.planner_temperature > 0) o.planner.temperature = a.planner_temperature;
  if (a.planner_smoothing >= 0) o.planner.smoothing = a.planner_smoothing;
  o.expert_policies = mj::expert_policies_for(m.expert_policies, o.env, o.planner);
  const mj::CollectReport r = mj::collect(o);
  if (!mpi_lead()) return;  // under MPI rank 0 reports the job
  double mean = 0;
  for (double v : r.returns) mean += v / std::max<size_t>(1, r.returns.size());
  std::printf("episodes in %s: %d (recorded now: %d, kept: %d), mean return %.1f\n", o.out.c_str(),
              r.episodes, r.recorded_now, r.episodes - r.recorded_now, mean);
  if (r.recorded_now > 0 && r.seconds > 0)
    std::printf("  recorded %ld frames in %.1f s (%.1f frames/s)\n", r.frames, r.seconds,
                r.frames / r.seconds);
}

void print_collect_summary(const CollectReport& r, const std::string& out) {
  std::map<std::string, int> by_outcome;
  double km = 0;
  int red = 0;
  for (const auto& e : r.episodes) {
    ++by_outcome[e.outcome];
    km += e.distance / 1000.0;
    red += e.red_light_violations;
  }
  int n = static_cast<int>(r.episodes.size());
  std::printf("episodes in %s: %d (recorded now: %d, kept: %d)\n", out.c_str(), n, r.recorded_now,
              n - r.recorded_now);
  for (const auto& [outcome, count] : by_outcome)
    std::printf("  %-10s %4d  (%.1f%%)\n", outcome.c_str(), count, 100.0 * count / std::max(1, n));
  std::printf("  driven %.2f km, red-light violations %d\n", km, red);
  if (r.recorded_now > 0 && r.seconds > 0)
    std::printf("  recorded %ld frames in %.1f s (%.0f frames/s)\n", r.frames, r.seconds,
                r.frames / r.seconds);
}

}  // namespace

void add_collect(CLI::App& app) {
  auto args = std::make_shared<CollectArgs>();
  CLI::App* sub = app.add_subcommand(
      "collect", "record expert episodes to HDF5 (driving, or MuJoCo-Image with --env)");
  sub->add_option("--config,-c", args->config, "TOML config (default: built-in quickstart)");
  sub->add_option("--episodes,-n", args->episodes,
                  "number of episodes (collect.episodes; with --env: mujoco.episodes.ENV)")
      ->check(CLI::PositiveNumber);
  sub->add_option("--workers,-j", args->workers, "worker processes (collect.workers)")
      ->check(CLI::PositiveNumber);
  sub->add_option("--seed", args->seed, "run seed (collect.seed)")->check(CLI::NonNegativeNumber);
  sub->add_option("--out,-o", args->out, "output folder (collect.out)");
  sub->add_option("--town", args->town, "town name or .net.xml path (world.town)");
  sub->add_option("--traffic", args->traffic, "empty | regular | dense (world.traffic)")
      ->check(CLI::IsMember({"empty", "regular", "dense"}));
  sub->add_flag("--noise", args->noise, "inject action noise (collect.noise.enabled)");
  sub->add_option("--png", args->png, "also write every BEV frame as PNG under this folder");
  CLI::Option* env = sub->add_option("--env", args->env,
                  "MuJoCo-Image environment (halfcheetah, hopper, ant, reacher, humanoid) "
                  "instead of driving; needs --out");
  sub->add_option("--size", args->size, "with --env: frame width and height in pixels (mujoco.size)")
      ->check(CLI::Range(8, 1024))
      ->needs(env);
  sub->add_option("--max-steps", args->max_steps,
                  "with --env: end episodes after this many steps (mujoco.max_steps; default: the env's "
                  "limit)")
      ->check(CLI::PositiveNumber)
      ->needs(env);
  sub->add_option("--planner-samples", args->planner_samples,
                  "with --env: the expert planner's rollouts per step (default per env)")
      ->check(CLI::PositiveNumber)
      ->needs(env);
  sub->add_option("--planner-iterations", args->planner_iterations,
                  "with --env: the expert planner's refinements per step (default per env)")
      ->check(CLI::PositiveNumber)
      ->needs(env);
  sub->add_option("--planner-sigma", args->planner_sigma,
                  "with --env: the planner's exploration noise, fraction of the half ctrlrange")
      ->check(CLI::Range(1e-6, 10.0))
      ->needs(env);
  sub->add_option("--planner-temperature", args->planner_temperature,
                  "with --env: the planner's weight temperature (default per env)")
      ->check(CLI::Range(1e-6, 1e6))
      ->needs(env);
  sub->add_option("--planner-smoothing", args->planner_smoothing,
                  "with --env: time correlation of the planner's noise, 0 (white) to <1")
      ->check(CLI::Range(0.0, 0.999))
      ->needs(env);
  sub->add_option("--planner-horizon", args->planner_horizon,
                  "with --env: the expert planner's rollout length in steps (default per env)")
      ->check(CLI::PositiveNumber)
      ->needs(env);
  sub->callback([args] {
    if (!args->env.empty()) return collect_mujoco(*args);
    Settings s = settings_from(args->config);
    if (args->episodes > 0) s.collect.episodes = args->episodes;
    if (args->workers > 0) s.collect.workers = args->workers;
    if (args->seed >= 0) s.collect.seed = static_cast<uint64_t>(args->seed);
    if (!args->out.empty()) s.collect.out = args->out;
    if (!args->town.empty()) s.world.town = args->town;
    if (!args->traffic.empty()) s.world.traffic = args->traffic;
    if (args->noise) s.collect.noise.enabled = true;
    CollectOptions opt;
    opt.png_dir = args->png;
    CollectReport r = collect(s, opt);
    if (!mpi_lead()) return;  // under MPI rank 0 reports the job
    print_collect_summary(r, s.collect.out);
  });
}

}  // namespace cd::cli
