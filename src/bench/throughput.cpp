#include "bench/throughput.hpp"

#include <chrono>
#include <cstdio>

#include <nlohmann/json.hpp>

#include "agents/agent.hpp"
#include "app/build_info.hpp"
#include "bench/interleaved.hpp"
#include "bench/runner.hpp"
#include "bench/suite.hpp"
#include "collect/expert_episode.hpp"
#include "core/rng.hpp"
#include "methods/method.hpp"
#include "world/world.hpp"

namespace cd {

namespace {
using Clock = std::chrono::steady_clock;
}  // namespace

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

}  // namespace cd
