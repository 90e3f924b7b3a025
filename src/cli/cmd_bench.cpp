#include <chrono>
#include <cstdio>
#include <functional>

#include <nlohmann/json.hpp>

#include "cli/commands.hpp"
#include "cli/common.hpp"
#include "agents/agent.hpp"
#include "bench/metrics.hpp"
#include "bench/runner.hpp"
#include "bench/suite.hpp"
#include "collect/expert_episode.hpp"
#include "methods/method.hpp"
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
    std::printf("%s\n", j.dump().c_str());
  } else {
    std::printf("closed loop on %s, %d episodes per agent, interleaved (one process)\n",
                suite.name.c_str(), episodes);
    std::printf("  %-10s %10.0f steps/s  (%ld steps)\n", agent_name.c_str(), rate, m.steps_b);
    std::printf("  %-10s %10.0f steps/s  (%ld steps)\n", "expert", expert_rate, m.steps_a);
    m.print_spread();
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
}

}  // namespace cd::cli
