#pragma once
// Benchmark suites (SPEC section 5): a town, a traffic level and a fixed list of tasks,
// generated once from a seed and kept as JSON files in the repo (suites/*.json, compiled into
// the binary), so every method meets exactly the same tasks.
#include <cstdint>
#include <string>
#include <vector>

#include <nlohmann/json_fwd.hpp>

#include "world/world.hpp"

namespace cd {

struct Suite {
  std::string name;
  std::string description;
  std::string town;     // a town name or a .net.xml path
  std::string traffic;  // empty | regular | dense
  int trials = 3;
  uint64_t seed = 0;    // what the tasks were generated from
  std::vector<Task> tasks;
};

// How a suite is generated.
struct SuiteRecipe {
  std::string name;
  std::string description;
  std::string town = "town-a";
  std::string traffic = "regular";
  int tasks = 25;
  int trials = 3;
  uint64_t seed = 0;
  double min_route_m = 300;
  double max_route_m = 700;
  std::vector<std::string> scenarios = {"route"};  // task i has scenarios[i % size]
};

// The recipes of the built-in suites: {town-a, town-b} x {empty, regular, dense, stopgo},
// quickstart, town-c's, and the verdicts' 100-task test suites verdicts-{town-a,town-b}-{regular,
// dense}.
const std::vector<SuiteRecipe>& builtin_suite_recipes();
std::vector<std::string> builtin_suite_names();

// A built-in suite by name, or a suite file by path. Throws ConfigError / DataError.
Suite load_suite(const std::string& name_or_path);
Suite suite_from_json(const nlohmann::json& j, const std::string& where);
nlohmann::json suite_to_json(const Suite& s);

// Generates the tasks of a recipe on `world`, which must run the recipe's town.
Suite generate_suite(const SuiteRecipe& recipe, World& world);

// The traffic seed of a trial of a task: trial 0 keeps the task's seed.
uint64_t trial_traffic_seed(const Task& task, int trial);
// Episode i of a suite run with `trials` trials per task: trial i % trials of task i / trials,
// with that trial's traffic seed (eval's numbering of episode records).
Task suite_episode_task(const Suite& suite, int trials, int i);

}  // namespace cd
