#include <cmath>
#include <chrono>
#include <cstdio>
#include <functional>

#include <nlohmann/json.hpp>

#include "app/build_info.hpp"
#include "cli/commands.hpp"
#include "cli/common.hpp"
#include "agents/agent.hpp"
#include "bench/metrics.hpp"
#include "bench/runner.hpp"
#include "bench/suite.hpp"
#include "bench/train_bench.hpp"
#include "collect/expert_episode.hpp"
#include "core/rng.hpp"
#include "methods/method.hpp"
#include "mujoco/env.hpp"
#include "mujoco/eval.hpp"
#include "mujoco/expert.hpp"
#include "world/world.hpp"

namespace cd::cli {

namespace {

using Clock = std::chrono::steady_clock;

// Two loops timed over the same slices, A B A B ...: a machine that slows down (another
// process, a frequency change) slows both loops of a slice alike, so the per-slice ratio
// holds where a ratio of two separate runs does not. The median ratio is the figure; the
// spread says how far to trust it.
struct Interleaved {
  std::vector<double> rate_a, rate_b, ratios;  // per slice; ratio = b / a
  long steps_a = 0, steps_b = 0;
  double seconds_a = 0, seconds_b = 0;

  void add(long sa, double ta, long sb, double tb) {
    steps_a += sa;
    steps_b += sb;
    seconds_a += ta;
    seconds_b += tb;
    rate_a.push_back(sa / ta);
    rate_b.push_back(sb / tb);
    ratios.push_back(rate_b.back() / rate_a.back());
  }
  double median() const { return *quantile(ratios, 0.5); }
  nlohmann::json spread_json() const {
    return {{"ratio_min", *quantile(ratios, 0.0)},
            {"ratio_q25", *quantile(ratios, 0.25)},
            {"ratio_q75", *quantile(ratios, 0.75)},
            {"ratio_max", *quantile(ratios, 1.0)},
            {"slices", static_cast<long>(ratios.size())}};
  }
  void print_spread() const {
    std::printf("  ratio       %10.3f  median of %zu slices (quartiles %.3f .. %.3f, range "
                "%.3f .. %.3f)\n",
                median(), ratios.size(), *quantile(ratios, 0.25), *quantile(ratios, 0.75),
                *quantile(ratios, 0.0), *quantile(ratios, 1.0));
  }
};

// Steps/s of bare SUMO (the ego driven by SUMO itself) and of the full loop (ego model,
// expert, BEV, checks, recording to memory), interleaved over `slices` tasks: each slice
// runs steps/slices steps of bare SUMO, then as many of the full loop, on the same task.
void bench_world(const Settings& s, long steps, int slices, bool json) {
  World world(s);
  ExpertRecorder recorder(world, s);
  const long per_slice = std::max<long>(1, steps / slices);
  Interleaved m;
  EpisodeData data;
  for (int k = 0; k < slices; ++k) {
    Task task = world.sample_task(episode_seed(s.collect.seed, k), s.collect.min_route_m,
                                  s.collect.max_route_m);
    task.timeout_s = 1e9;  // resets are not what is measured

    world.reset(task);
    world.hand_ego_to_sumo();
    auto t0 = Clock::now();
    for (long i = 0; i < per_slice; ++i) world.step_bare();
    const double bare = std::chrono::duration<double>(Clock::now() - t0).count();

    world.reset(task);
    long done = 0;
    double full = 0;
    while (done < per_slice) {
      // Timed like collection: the episode's buffer, then its steps; resets are not timed.
      auto t1 = Clock::now();
      recorder.begin(data);
      data.bev_packed.reserve(data.frame_pixels() * static_cast<size_t>(per_slice - done));
      StepResult r;
      for (; done < per_slice && r.outcome == Outcome::Running; ++done) {
        Control c = recorder.record_step(data);
        r = world.step(c);
      }
      full += std::chrono::duration<double>(Clock::now() - t1).count();
      if (r.outcome != Outcome::Running && done < per_slice) world.reset(task);
    }
    m.add(per_slice, bare, per_slice, full);
  }
  const double sumo_rate = m.steps_a / m.seconds_a, full_rate = m.steps_b / m.seconds_b;
  if (json) {
    nlohmann::json j = {{"sumo_steps_per_s", sumo_rate},
                        {"full_steps_per_s", full_rate},
                        {"ratio", m.median()}};
    j.update(m.spread_json());
    j["build"] = build_components();
    std::printf("%s\n", j.dump().c_str());
  } else {
    std::printf("world %s, %s traffic, %ld steps per loop in %d interleaved slices\n",
                s.world.town.c_str(), s.world.traffic.c_str(), m.steps_a, slices);
    std::printf("  bare SUMO   %10.0f steps/s\n", sumo_rate);
    std::printf("  full loop   %10.0f steps/s\n", full_rate);
    m.print_spread();
  }
}

// Closed-loop steps/s of an agent (observation history, inference, control, SUMO step,
// checks) on the first tasks of a suite, in this process, interleaved with the expert:
// episode i of the agent, then episode i of the expert on the same task, and so on.
void bench_eval(Settings s, const std::string& agent_name, const std::string& checkpoint,
                const std::string& suite_name, int episodes, bool json) {
  Suite suite = load_suite(suite_name);
  s.world.town = suite.town;
  s.world.traffic = suite.traffic;
  World world(s);
  auto episode = [&](const std::string& name, const std::string& ckpt, int i) {
    LoopStats stats;
    auto agent = make_agent(name, ckpt, s, &world);
    run_episode(world, *agent, suite.tasks[static_cast<size_t>(i) % suite.tasks.size()], s,
                &stats);
    return stats;
  };
  Interleaved m;  // a: the expert, b: the agent
  for (int i = 0; i < episodes; ++i) {
    const LoopStats a = episode(agent_name, checkpoint, i);
    const LoopStats x = episode("expert", "", i);
    m.add(x.steps, x.seconds, a.steps, a.seconds);
  }
  const double rate = m.steps_b / m.seconds_b, expert_rate = m.steps_a / m.seconds_a;
  if (json) {
    nlohmann::json j = {{"agent", agent_name},       {"suite", suite.name},
                        {"episodes", episodes},      {"steps", m.steps_b},
                        {"steps_per_s", rate},       {"expert_steps_per_s", expert_rate},
                        {"ratio_to_expert", m.median()}};
    j.update(m.spread_json());
    j["build"] = build_components();
    std::printf("%s\n", j.dump().c_str());
  } else {
    std::printf("closed loop on %s, %d episodes per agent, interleaved (one process)\n",
                suite.name.c_str(), episodes);
    std::printf("  %-10s %10.0f steps/s  (%ld steps)\n", agent_name.c_str(), rate, m.steps_b);
    std::printf("  %-10s %10.0f steps/s  (%ld steps)\n", "expert", expert_rate, m.steps_a);
    m.print_spread();
  }
}


// MuJoCo-Image: bare physics steps/s against physics + rendering (one frame per step, as
// collection and image policies need), per frame size, interleaved slice by slice in one
// process: physics, then each size, then physics again. The policy is a stand-in (uniform random
// actions, the same sequence for every loop; its cost is nil): a learned policy's inference is
// `bench eval`'s, and the planner expert's per-step cost, 1000s of physics steps, is measured
// apart (--expert-steps) so that it does not swamp the two figures measured here.
struct EnvBenchArgs {
  std::string env;
  std::vector<int> sizes{64};
  long steps = 2000;
  int slices = 6;
  int expert_steps = 0;
  uint64_t seed = 0;
  bool json = false;
};

void bench_env(const EnvBenchArgs& a) {
  mj::Env physics(a.env);  // never renders
  std::vector<std::unique_ptr<mj::Env>> renders;
  for (int size : a.sizes) {
    mj::EnvOptions o;
    o.width = o.height = size;
    renders.push_back(std::make_unique<mj::Env>(a.env, o));
  }
  const long per_slice = std::max<long>(1, a.steps / a.slices);
  const int dim = physics.action_dim();
  const std::vector<double> low = physics.action_low(), high = physics.action_high();
  std::vector<Interleaved> by_size(a.sizes.size());  // a: physics, b: physics + render
  Interleaved expert_m;                               // a: physics, b: + render + planner
  std::unique_ptr<mj::PlannerExpert> expert;
  if (a.expert_steps > 0) {
    mj::PlannerOptions p;
    p.seed = a.seed;
    expert = std::make_unique<mj::PlannerExpert>(a.env, p);
  }
  std::vector<uint8_t> frame;
  // Steps `n` actions of `actions` from the slice's start state; a terminated episode starts
  // again from it, untimed. Returns the seconds stepping (and rendering, planning) took.
  auto run = [&](mj::Env& env, const std::vector<double>& start, const std::vector<double>& actions,
                 long n, bool render, mj::PlannerExpert* planner) {
    env.set_state(start);
    if (planner != nullptr) planner->reset();
    if (render) frame.resize(env.frame_bytes());
    double seconds = 0;
    auto t0 = Clock::now();
    for (long i = 0; i < n; ++i) {
      std::span<const double> act(actions.data() + (i % per_slice) * dim, dim);
      std::vector<double> planned;
      if (planner != nullptr) {
        planned = planner->act(env.state());
        act = planned;
      }
      const mj::StepResult r = env.step(act);
      if (render) env.render(frame.data());
      if (r.terminated) {
        seconds += std::chrono::duration<double>(Clock::now() - t0).count();
        env.set_state(start);
        t0 = Clock::now();
      }
    }
    return seconds + std::chrono::duration<double>(Clock::now() - t0).count();
  };
  for (int k = 0; k < a.slices; ++k) {
    Rng rng(derive_seed(a.seed, static_cast<uint64_t>(k)));
    renders[0]->reset(episode_seed(a.seed, k));  // (reset renders: the physics env never does)
    const std::vector<double> start = renders[0]->state();
    std::vector<double> actions(static_cast<size_t>(per_slice) * dim);
    for (long i = 0; i < per_slice; ++i)
      for (int j = 0; j < dim; ++j) actions[i * dim + j] = rng.uniform(low[j], high[j]);
    const double bare = run(physics, start, actions, per_slice, false, nullptr);
    for (size_t s = 0; s < a.sizes.size(); ++s) {
      const double full = run(*renders[s], start, actions, per_slice, true, nullptr);
      by_size[s].add(per_slice, bare, per_slice, full);
    }
    if (expert) {
      const double planned = run(*renders[0], start, actions, a.expert_steps, true, expert.get());
      expert_m.add(per_slice, bare, a.expert_steps, planned);
    }
  }
  const Interleaved& first = by_size.front();
  const double physics_rate = first.steps_a / first.seconds_a;
  auto size_json = [&](size_t s) {
    const Interleaved& m = by_size[s];
    const double full = m.steps_b / m.seconds_b;
    nlohmann::json j = {{"size", a.sizes[s]},
                        {"full_steps_per_s", full},
                        {"render_share", 1.0 - m.median()},
                        {"render_ms_per_frame", 1e3 * (1.0 / full - 1.0 / physics_rate)}};
    j.update(m.spread_json());
    return j;
  };
  if (a.json) {
    nlohmann::json j = size_json(0);
    j["env"] = a.env;
    j["steps"] = first.steps_a;
    j["physics_steps_per_s"] = physics_rate;
    j["policy"] = "random";
    nlohmann::json sizes = nlohmann::json::array();
    for (size_t s = 0; s < a.sizes.size(); ++s) sizes.push_back(size_json(s));
    j["sizes"] = sizes;
    if (expert) {
      j["expert"] = expert->describe();
      j["expert_steps"] = expert_m.steps_b;
      j["expert_steps_per_s"] = expert_m.steps_b / expert_m.seconds_b;
      j["expert_s_per_step"] = expert_m.seconds_b / expert_m.steps_b;
    }
    j["build"] = build_components();
    std::printf("%s\n", j.dump().c_str());
    return;
  }
  std::printf("env %s, %ld steps per loop in %d interleaved slices, random actions\n",
              a.env.c_str(), first.steps_a, a.slices);
  std::printf("  physics      %10.0f steps/s\n", physics_rate);
  for (size_t s = 0; s < a.sizes.size(); ++s) {
    const nlohmann::json j = size_json(s);
    std::printf("  + render %3dx%-3d %7.0f steps/s  render %.0f%% of a step, %.3f ms/frame\n",
                a.sizes[s], a.sizes[s], j["full_steps_per_s"].get<double>(),
                100 * j["render_share"].get<double>(), j["render_ms_per_frame"].get<double>());
    by_size[s].print_spread();
  }
  if (expert) {
    std::printf("  + render %dx%d + expert (%s): %.3f s/step over %ld steps\n", a.sizes[0],
                a.sizes[0], expert->describe().c_str(), expert_m.seconds_b / expert_m.steps_b,
                expert_m.steps_b);
  }
}

// The planner expert in closed loop from a seeded reset: its return and cost per step.
void bench_expert(const std::string& env_name, const mj::PlannerOptions& options, int steps,
                  uint64_t seed, bool json) {
  mj::Env env(env_name);
  mj::PlannerOptions p = options;
  p.seed = derive_seed(seed, 1);
  mj::PlannerExpert expert(env_name, p);
  env.reset(seed);
  const int limit = steps > 0 ? std::min(steps, env.max_steps()) : env.max_steps();
  double ret = 0;
  int done = 0;
  bool terminated = false;
  const auto t0 = Clock::now();
  std::vector<float> actions;  // the copycat measure of eval --env, for the expert's own actions
  for (; done < limit && !terminated; ++done) {
    const std::vector<double> a = expert.act(env.state());
    actions.insert(actions.end(), a.begin(), a.end());
    const mj::StepResult r = env.step(a);
    ret += r.reward;
    terminated = r.terminated;
    if (!json && (done + 1) % 100 == 0) {
      std::fprintf(stderr, "  step %d: return %.1f, x %.2f\n", done + 1, ret, env.state()[0]);
    }
  }
  const double seconds = std::chrono::duration<double>(Clock::now() - t0).count();
  const double r2 = mj::lag1_r2({actions}, env.action_dim());
  if (json) {
    nlohmann::json j = {{"env", env_name},
                        {"expert", expert.describe()},
                        {"seed", seed},
                        {"return", ret},
                        {"steps", done},
                        {"terminated", terminated},
                        {"seconds", seconds},
                        {"s_per_step", seconds / std::max(1, done)},
                        {"simulated_steps", expert.simulated_steps()},
                        {"action_lag1_r2", std::isfinite(r2) ? nlohmann::json(r2) : nlohmann::json()}};
    j["build"] = build_components();
    std::printf("%s\n", j.dump().c_str());
  } else {
    std::printf("%s, %s, seed %llu: return %.1f over %d steps%s, %.3f s/step (%.0f s), "
                "action lag-1 R2 %.3f\n",
                env_name.c_str(), expert.describe().c_str(),
                static_cast<unsigned long long>(seed), ret, done,
                terminated ? " (terminated)" : "", seconds / std::max(1, done), seconds, r2);
  }
}

}  // namespace

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
  world->callback([=] { bench_world(settings_from(*config), *steps, *slices, *json); });

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
  ev->callback([=] {
    bench_eval(settings_from(*config), *agent, *checkpoint, *suite, *episodes, *json);
  });

  auto env_args = std::make_shared<EnvBenchArgs>();
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
  en->callback([=] { bench_env(*env_args); });

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
  ex->callback([=] { bench_expert(*ex_env, *ex_opts, *ex_steps, *ex_seed, *json); });

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
  });
}

}  // namespace cd::cli
