#include <chrono>
#include <cstdio>

#include <nlohmann/json.hpp>

#include "cli/commands.hpp"
#include "cli/common.hpp"
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
}

}  // namespace cd::cli
