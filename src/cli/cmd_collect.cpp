#include <cstdio>
#include <map>

#include "cli/commands.hpp"
#include "cli/common.hpp"
#include "collect/collect.hpp"

namespace cd::cli {

namespace {

struct CollectArgs {
  std::string config, out, png, town, traffic;
  int episodes = 0, workers = 0;
  int64_t seed = -1;
  bool noise = false;
};

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
  CLI::App* sub = app.add_subcommand("collect", "record expert driving episodes to HDF5");
  sub->add_option("--config,-c", args->config, "TOML config (default: built-in quickstart)");
  sub->add_option("--episodes,-n", args->episodes, "number of episodes (collect.episodes)")
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
  sub->callback([args] {
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
    print_collect_summary(r, s.collect.out);
  });
}

}  // namespace cd::cli
