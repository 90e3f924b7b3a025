#include <cstdio>

#include <nlohmann/json.hpp>

#include "bench/suite.hpp"
#include "cli/commands.hpp"
#include "cli/common.hpp"
#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "core/run_lock.hpp"

namespace cd::cli {

namespace {

struct SuiteArgs {
  std::string config, builtin, name, town = "town-a", traffic = "regular", out;
  std::vector<std::string> scenarios = {"route"};
  int tasks = 25, trials = 3;
  uint64_t seed = 0;
  double min_route = 300, max_route = 700;
};

// Generates a suite on its town (a fresh World: one SUMO per process).
void generate(const Settings& base, const SuiteRecipe& r, const std::string& out) {
  Settings s = base;
  s.world.town = r.town;
  s.world.traffic = r.traffic;
  World world(s);
  Suite suite = generate_suite(r, world);
  write_file_atomic(out, suite_to_json(suite).dump(1) + "\n");
  std::printf("%s: %zu tasks on %s (%s traffic) -> %s\n", suite.name.c_str(), suite.tasks.size(),
              suite.town.c_str(), suite.traffic.c_str(), out.c_str());
}

}  // namespace

void add_suite(CLI::App& app) {
  auto a = std::make_shared<SuiteArgs>();
  CLI::App* sub = app.add_subcommand(
      "suite", "generate benchmark suites (the built-in ones live in suites/*.json)");
  sub->add_option("--config,-c", a->config, "TOML config (world settings used to generate)");
  sub->add_option("--builtin", a->builtin,
                  "regenerate one built-in suite by name, or 'all', into --out (a folder)");
  sub->add_option("--name", a->name, "name of a new suite");
  sub->add_option("--town", a->town, "town name or .net.xml path");
  sub->add_option("--traffic", a->traffic, "empty | regular | dense")
      ->check(CLI::IsMember({"empty", "regular", "dense"}));
  sub->add_option("--scenarios", a->scenarios, "route | red_light | leader (cycled over tasks)")
      ->check(CLI::IsMember({"route", "red_light", "leader"}));
  sub->add_option("--tasks", a->tasks, "number of tasks")->check(CLI::PositiveNumber);
  sub->add_option("--trials", a->trials, "trials per task")->check(CLI::PositiveNumber);
  sub->add_option("--seed", a->seed, "generation seed");
  sub->add_option("--min-route", a->min_route, "m, shortest route");
  sub->add_option("--max-route", a->max_route, "m, longest route");
  sub->add_option("--out,-o", a->out, "output file (a folder with --builtin)")->required();
  sub->callback([a] {
    Settings s = settings_from(a->config);
    if (!a->builtin.empty()) {
      // The built-in suites are drawn by a route-mode ego, whatever the config says: a task
      // it can drive needs no lane change, so both modes drive every built-in task.
      Settings route = s;
      route.ego.lateral = "route";
      const RunLock lock = lock_run_folder(a->out, "suite");
      bool any = false;
      for (const SuiteRecipe& r : builtin_suite_recipes()) {
        if (a->builtin != "all" && a->builtin != r.name) continue;
        any = true;
        generate(route, r, a->out + "/" + r.name + ".json");
      }
      if (!any) throw ConfigError("unknown built-in suite '" + a->builtin + "'");
      return;
    }
    if (a->max_route < a->min_route) throw ConfigError("--max-route must be >= --min-route");
    SuiteRecipe r;
    r.name = a->name.empty() ? a->town + "-" + a->traffic : a->name;
    r.description = "generated with causaldrive suite";
    r.town = a->town;
    r.traffic = a->traffic;
    r.tasks = a->tasks;
    r.trials = a->trials;
    r.seed = a->seed;
    r.min_route_m = a->min_route;
    r.max_route_m = a->max_route;
    r.scenarios = a->scenarios;
    generate(s, r, a->out);
  });
}

}  // namespace cd::cli
