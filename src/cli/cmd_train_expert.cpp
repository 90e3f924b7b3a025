#include <cstdio>
#include <memory>
#include <string>

#include "cli/commands.hpp"
#include "core/build_parts.hpp"
#include "core/progress.hpp"
#include "mujoco/env_spec.hpp"
#include "mujoco/sac.hpp"

namespace cd::cli {

void add_train_expert(CLI::App& app) {
  auto o = std::make_shared<mj::SacOptions>();
  auto env = std::make_shared<std::string>();
  auto out = std::make_shared<std::string>();
  CLI::App* sub = app.add_subcommand(
      "train-expert", "train a MuJoCo-Image state expert with soft actor-critic (the expert "
                      "[mujoco] expert_policies selects); resumes from FILE.resume when "
                      "rerun");
  sub->add_option("--env", *env, "halfcheetah, hopper, ant, reacher or humanoid")->required();
  sub->add_option("--out,-o", *out, "policy file (default: experts/ENV.pt; ENV.json beside it)");
  sub->add_option("--steps", o->steps, "env steps, one update each (default 300000)")
      ->check(CLI::PositiveNumber);
  sub->add_option("--start-steps", o->start_steps,
                  "uniform random actions first (default 10000)")
      ->check(CLI::NonNegativeNumber);
  sub->add_option("--eval-every", o->eval_every,
                  "env steps between evaluations; the best is saved (default 10000)")
      ->check(CLI::PositiveNumber);
  sub->add_option("--eval-episodes", o->eval_episodes, "episodes per evaluation (default 5)")
      ->check(CLI::PositiveNumber);
  sub->add_option("--hidden", o->hidden, "width of the two hidden layers (default 256)")
      ->check(CLI::PositiveNumber);
  sub->add_option("--batch", o->batch, "minibatch (default 256)")->check(CLI::PositiveNumber);
  sub->add_option("--lr", o->lr, "Adam learning rate (default 3e-4)")->check(CLI::PositiveNumber);
  sub->add_option("--seed", o->seed, "seed (default 0)");
  sub->add_option("--threads", o->threads, "torch threads (default 1)")
      ->check(CLI::PositiveNumber);
  sub->add_option("--device", o->device, "where the networks train: auto | cpu | cuda (default cpu)")
      ->check(CLI::IsMember({"auto", "cpu", "cuda"}));
  sub->callback([o, env, out] {
    require_mujoco("train-expert");
    mj::env_spec(*env);  // an unknown env: one line
    const std::string path = out->empty() ? "experts/" + *env + ".pt" : *out;
    const mj::SacReport r = mj::train_sac(*env, *o, path, [](const std::string& l) { log_line(l); });
    std::printf("%s: best return %.1f +- %.1f at %ld steps; %ld steps in %s (%ld episodes)\n",
                path.c_str(), r.best.mean_return, r.best.sd_return, r.best.steps, o->steps,
                format_duration(r.seconds).c_str(), r.episodes);
  });
}

}  // namespace cd::cli
