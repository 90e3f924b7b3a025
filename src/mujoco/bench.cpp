#include "mujoco/bench.hpp"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <memory>
#include <span>

#include <nlohmann/json.hpp>

#include "app/build_info.hpp"
#include "bench/interleaved.hpp"
#include "collect/expert_episode.hpp"
#include "core/rng.hpp"
#include "mujoco/env.hpp"
#include "mujoco/eval.hpp"

namespace cd::mj {

namespace {
using Clock = std::chrono::steady_clock;
}  // namespace

// MuJoCo-Image: bare physics steps/s against physics + rendering (one frame per step, as
// collection and image policies need), per frame size, interleaved slice by slice in one
// process: physics, then each size, then physics again. The policy is a stand-in (uniform random
// actions, the same sequence for every loop; its cost is nil): a learned policy's inference is
// `bench eval`'s, and the planner expert's per-step cost, 1000s of physics steps, is measured
// apart (--expert-steps) so that it does not swamp the two figures measured here.
void bench_env(const EnvBenchArgs& a) {
  Env physics(a.env);  // never renders
  std::vector<std::unique_ptr<Env>> renders;
  for (int size : a.sizes) {
    EnvOptions o;
    o.width = o.height = size;
    renders.push_back(std::make_unique<Env>(a.env, o));
  }
  const long per_slice = std::max<long>(1, a.steps / a.slices);
  const int dim = physics.action_dim();
  const std::vector<double> low = physics.action_low(), high = physics.action_high();
  std::vector<Interleaved> by_size(a.sizes.size());  // a: physics, b: physics + render
  Interleaved expert_m;                               // a: physics, b: + render + planner
  std::unique_ptr<PlannerExpert> expert;
  if (a.expert_steps > 0) {
    PlannerOptions p;
    p.seed = a.seed;
    expert = std::make_unique<PlannerExpert>(a.env, p);
  }
  std::vector<uint8_t> frame;
  // Steps `n` actions of `actions` from the slice's start state; a terminated episode starts
  // again from it, untimed. Returns the seconds stepping (and rendering, planning) took.
  auto run = [&](Env& env, const std::vector<double>& start, const std::vector<double>& actions,
                 long n, bool render, PlannerExpert* planner) {
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
      const StepResult r = env.step(act);
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
void bench_expert(const std::string& env_name, const PlannerOptions& options, int steps,
                  uint64_t seed, bool json) {
  Env env(env_name);
  PlannerOptions p = options;
  p.seed = derive_seed(seed, 1);
  PlannerExpert expert(env_name, p);
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
    const StepResult r = env.step(a);
    ret += r.reward;
    terminated = r.terminated;
    if (!json && (done + 1) % 100 == 0) {
      std::fprintf(stderr, "  step %d: return %.1f, x %.2f\n", done + 1, ret, env.state()[0]);
    }
  }
  const double seconds = std::chrono::duration<double>(Clock::now() - t0).count();
  const double r2 = lag1_r2({actions}, env.action_dim());
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

}  // namespace cd::mj
