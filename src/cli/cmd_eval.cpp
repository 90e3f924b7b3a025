#include <cstdio>

#include <nlohmann/json.hpp>

#include "bench/runner.hpp"
#include "cli/commands.hpp"
#include "cli/common.hpp"
#include "core/error.hpp"
#include "core/mpi.hpp"
#include "methods/method.hpp"
#include "mujoco/eval.hpp"
#include "mujoco/expert.hpp"

namespace cd::cli {

namespace {

struct EvalArgs {
  std::string config, agent, checkpoint, suite, out, label, sensor, cim_path, device;
  int workers = 0, trials = 0;
  bool list = false, quiet = false, trace = false, record = false;
  // MuJoCo-Image (--env)
  std::string env;
  int episodes = 0, max_steps = 0;
  int64_t seed = -1;
};

// eval --env NAME: the MuJoCo-Image domain, with the [mujoco] settings of --config; the
// driving options do not apply.
void eval_mujoco(const EvalArgs& a) {
  for (const auto& [given, flag] : {std::pair{!a.suite.empty(), "--suite"},
                                    {a.trials > 0, "--trials"},
                                    {!a.sensor.empty(), "--sensor"},
                                    {!a.cim_path.empty(), "--cim-path"},
                                    {a.trace, "--trace"}}) {
    if (given) throw ConfigError(std::string(flag) + " is a driving option; it does not apply with --env");
  }
  const Settings s = settings_from(a.config);
  mj::EvalOptions o;
  o.env = a.env;
  o.agent = a.agent;
  o.label = a.label;
  o.checkpoint = a.checkpoint;
  o.out = a.out;
  o.episodes = a.episodes > 0 ? a.episodes : s.mujoco.eval_episodes;
  o.workers = a.workers > 0 ? a.workers : s.mujoco.workers;
  if (a.seed >= 0) o.seed = static_cast<uint64_t>(a.seed);
  o.max_steps = a.max_steps > 0 ? a.max_steps : s.mujoco.max_steps;
  o.planner = mj::planner_options(s.mujoco);
  o.expert_policies = mj::expert_policies_for(s.mujoco.expert_policies, o.env, o.planner);
  o.quiet = a.quiet;
  o.device = a.device.empty() ? s.eval.device : a.device;
  o.record = a.record;
  o.batch = s.eval.batch;
  const mj::EvalReport r = mj::evaluate(o);
  if (!mpi_lead()) return;  // under MPI rank 0 reports the job
  std::printf("%s", mj::eval_table(r.results).c_str());
  std::printf("results: %s/results.json (%d episodes run now", o.out.c_str(), r.run_now);
  if (r.run_now > 0 && r.seconds > 0)
    std::printf(", %ld steps in %.1f s, %.0f steps/s", r.steps, r.seconds, r.steps / r.seconds);
  std::printf(")\n");
}

void list_suites() {
  std::printf("built-in suites:\n");
  for (const SuiteRecipe& r : builtin_suite_recipes()) {
    Suite s = load_suite(r.name);
    std::printf("  %-16s %-7s %-8s %3zu tasks x %d trials  %s\n", s.name.c_str(), s.town.c_str(),
                s.traffic.c_str(), s.tasks.size(), s.trials, s.description.c_str());
  }
  std::printf("agents:");
  for (const MethodSpec& m : methods())
    std::printf(" %s%s", m.name, m.train ? " (--checkpoint)" : "");
  std::printf("\n");
}

}  // namespace

void add_eval(CLI::App& app) {
  auto a = std::make_shared<EvalArgs>();
  CLI::App* sub = app.add_subcommand("eval", "evaluate an agent closed-loop on a benchmark suite");
  sub->add_option("--config,-c", a->config, "TOML config (default: built-in quickstart)");
  std::string agents;
  for (const MethodSpec& m : methods()) agents += (agents.empty() ? "" : " | ") + std::string(m.name);
  sub->add_option("--agent", a->agent, agents);
  sub->add_option("--checkpoint", a->checkpoint, "training output folder of a learned agent");
  sub->add_option("--suite", a->suite, "built-in suite name or suite file (eval.suite)");
  sub->add_option("--workers,-j", a->workers, "worker processes (eval.workers)")
      ->check(CLI::PositiveNumber);
  sub->add_option("--trials", a->trials, "trials per task (default: the suite's)")
      ->check(CLI::PositiveNumber);
  sub->add_option("--out,-o", a->out, "output folder (eval.out); a rerun resumes");
  sub->add_option("--sensor", a->sensor,
                  "clean | shifted: the agent's BEV, shifted = seed 001's new-weather stand-in "
                  "(eval.sensor)")
      ->check(CLI::IsMember({"clean", "shifted"}));
  sub->add_option("--label", a->label, "row name in tables (default: the agent name)");
  sub->add_option("--cim-path", a->cim_path,
                  "free-steering cim: the dim/rip run whose planned path it steers along "
                  "(eval.cim_path)");
  CLI::Option* env = sub->add_option(
      "--env", a->env,
      "MuJoCo-Image environment (halfcheetah, hopper, ant, reacher, humanoid) instead of a "
      "driving suite; agents: expert, random or a family method with --checkpoint; needs --out");
  sub->add_option("--episodes,-n", a->episodes, "with --env: seeded episodes (mujoco.eval_episodes)")
      ->check(CLI::PositiveNumber)
      ->needs(env);
  sub->add_option("--seed", a->seed, "with --env: run seed of the episodes' initial states")
      ->check(CLI::NonNegativeNumber)
      ->needs(env);
  sub->add_option("--max-steps", a->max_steps,
                  "with --env: end episodes after this many steps (default: the env's limit)")
      ->check(CLI::PositiveNumber)
      ->needs(env);
  sub->add_option("--device", a->device,
                  "where the agents' networks run: auto | cpu | cuda (eval.device)")
      ->check(CLI::IsMember({"auto", "cpu", "cuda"}));
  sub->add_flag("--list-suites", a->list, "list the built-in suites and agents");
  sub->add_flag("--quiet,-q", a->quiet, "no progress output");
  sub->add_flag("--record", a->record,
                "also record each episode as the agent drove it: episodes/episode_NNNNNN.h5 in "
                "collect's layout (the frames the agent saw, speed, its controls, pose, causes), "
                "for the replays of `report --html`");
  sub->add_flag("--trace", a->trace,
                "also write episodes/episode_NNNNNN.trace.csv: one line per step (speed, path "
                "free, light, leader, command, controls)");
  sub->callback([a] {
    if (a->list) return list_suites();
    if (a->agent.empty()) throw ConfigError("eval needs --agent NAME (see --list-suites)");
    if (!a->env.empty()) return eval_mujoco(*a);
    Settings s = settings_from(a->config);
    if (!a->suite.empty()) s.eval.suite = a->suite;
    if (a->workers > 0) s.eval.workers = a->workers;
    if (a->trials > 0) s.eval.trials = a->trials;
    if (!a->out.empty()) s.eval.out = a->out;
    if (!a->sensor.empty()) s.eval.sensor = a->sensor;
    if (!a->cim_path.empty()) s.eval.cim_path = a->cim_path;
    if (!a->device.empty()) s.eval.device = a->device;
    EvalRequest req;
    req.agent = a->agent;
    req.checkpoint = a->checkpoint;
    req.label = a->label;
    req.quiet = a->quiet;
    req.trace = a->trace;
    req.record = a->record;
    EvalReport r = run_eval(s, req);
    if (!mpi_lead()) return;  // under MPI rank 0 reports the job
    std::printf("%s", results_table(r.results).c_str());
    std::printf("results: %s/results.json (%d episodes run now", s.eval.out.c_str(), r.run_now);
    if (r.run_now > 0 && r.seconds > 0)
      std::printf(", %ld steps in %.1f s, %.0f steps/s", r.steps, r.seconds, r.steps / r.seconds);
    std::printf(")\n");
    const long failed = r.results["summary"]["infrastructure_failures"].get<long>();
    if (failed > 0) {
      // Name the first one's cause: a crash is retried by a rerun, a task the ego cannot drive
      // (a route-mode ego on a route that needs a lane change) is refused again.
      std::string first;
      for (const auto& e : r.results["episodes"])
        if (e.value("outcome", "") == "infrastructure_failure") {
          first = e.value("failure", "");
          break;
        }
      std::fprintf(stderr,
                   "causaldrive: warning: %ld episode(s) failed for reasons outside the agent "
                   "(the first: %s); they are not counted; rerun the same command to retry "
                   "them\n",
                   failed, first.empty() ? "no reason recorded" : first.c_str());
    }
  });
}

}  // namespace cd::cli
