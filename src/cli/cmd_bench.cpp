#include <chrono>
#include <cstdio>

#include <nlohmann/json.hpp>

#include "cli/commands.hpp"
#include "cli/common.hpp"
#include "agents/agent.hpp"
#include "bench/runner.hpp"
#include "bench/suite.hpp"
#include "collect/expert_episode.hpp"
#include "world/world.hpp"

namespace cd::cli {

namespace {

using Clock = std::chrono::steady_clock;

// Steps/s of bare SUMO (the ego driven by SUMO itself) and of the full loop (ego model,
// expert, BEV, checks, recording to memory) on the same task, measured in one process.
void bench_world(const Settings& s, long steps, bool json) {
  World world(s);
  ExpertRecorder recorder(world, s);
  Task task = world.sample_task(episode_seed(s.collect.seed, 0), s.collect.min_route_m,
                                s.collect.max_route_m);
  task.timeout_s = 1e9;  // one long episode: resets are not what is measured

  world.reset(task);
  world.hand_ego_to_sumo();
  auto t0 = Clock::now();
  for (long i = 0; i < steps; ++i) world.step_bare();
  double bare = std::chrono::duration<double>(Clock::now() - t0).count();

  world.reset(task);
  EpisodeData data;
  long done = 0;
  double full = 0;
  while (done < steps) {
    // Timed like collection: the episode's buffer, then its steps; resets are not timed.
    auto t1 = Clock::now();
    recorder.begin(data);
    data.bev_packed.reserve(data.frame_pixels() * static_cast<size_t>(steps - done));
    StepResult r;
    for (; done < steps && r.outcome == Outcome::Running; ++done) {
      Control c = recorder.record_step(data);
      r = world.step(c);
    }
    full += std::chrono::duration<double>(Clock::now() - t1).count();
    if (r.outcome != Outcome::Running && done < steps) world.reset(task);
  }
  double sumo_rate = steps / bare, full_rate = steps / full;
  if (json) {
    nlohmann::json j = {{"sumo_steps_per_s", sumo_rate},
                        {"full_steps_per_s", full_rate},
                        {"ratio", full_rate / sumo_rate}};
    std::printf("%s\n", j.dump().c_str());
  } else {
    std::printf("world %s, %s traffic, %ld steps\n", s.world.town.c_str(), s.world.traffic.c_str(),
                steps);
    std::printf("  bare SUMO   %10.0f steps/s\n", sumo_rate);
    std::printf("  full loop   %10.0f steps/s\n", full_rate);
    std::printf("  ratio       %10.3f\n", full_rate / sumo_rate);
  }
}

// Closed-loop steps/s of an agent (observation history, inference, control, SUMO step,
// checks) on the first tasks of a suite, in this process, against the expert on the same
// tasks in the same run.
void bench_eval(Settings s, const std::string& agent_name, const std::string& checkpoint,
                const std::string& suite_name, int episodes, bool json) {
  Suite suite = load_suite(suite_name);
  s.world.town = suite.town;
  s.world.traffic = suite.traffic;
  World world(s);
  auto measure = [&](const std::string& name, const std::string& ckpt) {
    LoopStats stats;
    for (int i = 0; i < episodes; ++i) {
      auto agent = make_agent(name, ckpt, s);
      run_episode(world, *agent, suite.tasks[static_cast<size_t>(i) % suite.tasks.size()], s,
                  &stats);
    }
    return stats;
  };
  LoopStats a = measure(agent_name, checkpoint);
  LoopStats x = measure("expert", "");
  const double rate = a.steps / a.seconds, expert_rate = x.steps / x.seconds;
  if (json) {
    nlohmann::json j = {{"agent", agent_name},       {"suite", suite.name},
                        {"episodes", episodes},      {"steps", a.steps},
                        {"steps_per_s", rate},       {"expert_steps_per_s", expert_rate},
                        {"ratio_to_expert", rate / expert_rate}};
    std::printf("%s\n", j.dump().c_str());
  } else {
    std::printf("closed loop on %s, %d episodes (one process)\n", suite.name.c_str(), episodes);
    std::printf("  %-10s %10.0f steps/s  (%ld steps)\n", agent_name.c_str(), rate, a.steps);
    std::printf("  %-10s %10.0f steps/s  (%ld steps)\n", "expert", expert_rate, x.steps);
  }
}

}  // namespace

void add_bench(CLI::App& app) {
  CLI::App* bench = app.add_subcommand("bench", "throughput benchmarks");
  bench->require_subcommand(1);
  auto config = std::make_shared<std::string>();
  auto steps = std::make_shared<long>(3000);
  auto json = std::make_shared<bool>(false);
  CLI::App* world = bench->add_subcommand("world", "bare SUMO stepping against the full loop");
  world->add_option("--config,-c", *config, "TOML config (default: built-in quickstart)");
  world->add_option("--steps", *steps, "steps measured for each of the two loops")
      ->check(CLI::PositiveNumber);
  world->add_flag("--json", *json, "print one JSON object");
  world->callback([=] { bench_world(settings_from(*config), *steps, *json); });

  auto agent = std::make_shared<std::string>();
  auto checkpoint = std::make_shared<std::string>();
  auto suite = std::make_shared<std::string>("town-a-regular");
  auto episodes = std::make_shared<int>(5);
  CLI::App* ev = bench->add_subcommand(
      "eval", "closed-loop steps/s of an agent, inference included, against the expert");
  ev->add_option("--config,-c", *config, "TOML config (default: built-in quickstart)");
  ev->add_option("--agent", *agent, "expert | cs | bc-so | bc-oh")->required();
  ev->add_option("--checkpoint", *checkpoint, "training output folder of a learned agent");
  ev->add_option("--suite", *suite, "suite whose first tasks are driven");
  ev->add_option("--episodes", *episodes, "episodes per agent")->check(CLI::PositiveNumber);
  ev->add_flag("--json", *json, "print one JSON object");
  ev->callback([=] {
    bench_eval(settings_from(*config), *agent, *checkpoint, *suite, *episodes, *json);
  });
}

}  // namespace cd::cli
