#include <cstdio>
#include <map>

#include "cli/commands.hpp"
#include "cli/common.hpp"
#include "bench/report.hpp"
#include "bench/runner.hpp"
#include "collect/collect.hpp"
#include "world/town.hpp"

namespace cd::cli {

void add_quickstart(CLI::App& app) {
  auto config = std::make_shared<std::string>();
  auto out = std::make_shared<std::string>();
  CLI::App* sub = app.add_subcommand(
      "quickstart", "the main job: generate the towns, record expert demonstrations, evaluate the expert and the constant-speed baseline");
  sub->add_option("--config,-c", *config, "TOML config (default: built-in quickstart)");
  sub->add_option("--out,-o", *out, "data folder (collect.out)");
  sub->callback([config, out] {
    Settings s = settings_from(*config);
    if (!out->empty()) s.collect.out = *out;
    std::printf("causaldrive quickstart\n");
    for (const auto& name : town_names())
      std::printf("  town %-7s %s\n", name.c_str(), ensure_town_net(name).c_str());
    std::printf("recording %d expert episodes in %s, %s traffic, %d workers -> %s\n",
                s.collect.episodes, s.world.town.c_str(), s.world.traffic.c_str(),
                s.collect.workers, s.collect.out.c_str());
    std::fflush(stdout);  // keep this header above the progress lines on stderr
    CollectReport r = collect(s);
    std::map<std::string, int> n;
    for (const auto& e : r.episodes) ++n[e.outcome];
    int total = static_cast<int>(r.episodes.size());
    std::printf("\n| agent  | episodes | success | collision | timeout |\n");
    std::printf("|--------|----------|---------|-----------|---------|\n");
    std::printf("| expert | %8d | %6.1f%% | %8.1f%% | %6.1f%% |\n", total,
                100.0 * n["success"] / total, 100.0 * n["collision"] / total,
                100.0 * n["timeout"] / total);
    std::printf("\ndata: %s (one HDF5 file per episode, see README 'Data format')\n",
                s.collect.out.c_str());

    // The closed-loop benchmark on the quickstart suite: the expert and the constant-speed
    // baseline (the collision upper bound).
    const std::string eval_root = s.eval.out;
    std::vector<std::string> runs;
    for (const char* agent : {"expert", "cs"}) {
      Settings e = s;
      e.eval.out = eval_root + "/" + agent;
      std::printf("\nevaluating %s on suite %s -> %s\n", agent, e.eval.suite.c_str(),
                  e.eval.out.c_str());
      std::fflush(stdout);
      run_eval(e, EvalRequest{agent, "", "", false});
      runs.push_back(e.eval.out);
    }
    std::vector<RunResult> results;
    for (const auto& f : find_result_files(runs)) results.push_back(load_result(f));
    std::printf("\n%s", render_markdown(build_report(results), parse_metric_sets("outcomes,stopgo")).c_str());
    std::printf("\nresults: %s/<agent>/results.json; `causaldrive report %s` prints the tables again\n",
                eval_root.c_str(), eval_root.c_str());
  });
}

}  // namespace cd::cli
