#include <filesystem>
#include <chrono>
#include <cstdio>
#include <map>

#include "bench/html_report.hpp"
#include "bench/report.hpp"
#include "bench/runner.hpp"
#include "cli/commands.hpp"
#include "cli/common.hpp"
#include "collect/collect.hpp"
#include "core/atomic_file.hpp"
#include "core/progress.hpp"
#include "methods/method.hpp"
#include "train/request.hpp"
#include "world/town.hpp"

namespace cd::cli {

namespace {

void heading(const std::string& text) {
  std::printf("\n== %s\n", text.c_str());
  std::fflush(stdout);  // keep it above the progress lines on stderr
}

}  // namespace

void add_quickstart(CLI::App& app) {
  auto config = std::make_shared<std::string>();
  auto out = std::make_shared<std::string>();
  CLI::App* sub = app.add_subcommand(
      "quickstart",
      "the main job: generate the towns, record expert demonstrations, train bc-oh and cim "
      "(beta-VAE, Granger cause selection, speed predictor), evaluate the expert, cs, bc-oh and "
      "cim in closed loop and print the comparison table");
  sub->add_option("--config,-c", *config, "TOML config (default: built-in quickstart)");
  sub->add_option("--out,-o", *out, "data folder (collect.out)");
  sub->callback([config, out] {
    const auto t0 = std::chrono::steady_clock::now();
    Settings s = settings_from(*config);
    if (!out->empty()) s.collect.out = *out;
    std::printf("causaldrive quickstart\n");
    for (const auto& name : town_names())
      std::printf("  town %-7s %s\n", name.c_str(), ensure_town_net(name).c_str());

    heading("1/4 recording " + std::to_string(s.collect.episodes) + " expert episodes in " +
            s.world.town + ", " + s.world.traffic + " traffic, " +
            std::to_string(s.collect.workers) + " workers -> " + s.collect.out);
    CollectReport r = collect(s);
    std::map<std::string, int> n;
    for (const auto& e : r.episodes) ++n[e.outcome];
    std::printf("recorded %zu episodes: %d success, %d collision, %d timeout (one HDF5 file per "
                "episode, see README 'Data format')\n",
                r.episodes.size(), n["success"], n["collision"], n["timeout"]);

    // Both learners see the same recorded episodes; their folders resume on a rerun.
    const std::string train_root = s.train.out;
    TrainRequest bc{"bc-oh", s.collect.out, train_root + "/bc-oh", false, "", ""};
    heading("2/4 training bc-oh (behaviour cloning from " + std::to_string(s.model.history) +
            " stacked frames) -> " + bc.out_dir);
    print_train_summary(train_method(s, bc));
    TrainRequest cim{"cim", s.collect.out, train_root + "/cim", false, "", ""};
    heading("3/4 training cim: beta-VAE, Granger cause selection, causal speed predictor -> " +
            cim.out_dir);
    print_train_summary(train_method(s, cim));

    heading("4/4 closed-loop evaluation on suite " + s.eval.suite);
    const std::string eval_root = s.eval.out;
    std::vector<std::string> runs;
    const std::vector<std::pair<std::string, std::string>> agents = {
        {"expert", ""}, {"cs", ""}, {"bc-oh", bc.out_dir}, {"cim", cim.out_dir}};
    for (const auto& [agent, checkpoint] : agents) {
      Settings e = s;
      e.eval.out = eval_root + "/" + agent;
      std::printf("evaluating %s -> %s\n", agent.c_str(), e.eval.out.c_str());
      std::fflush(stdout);
      EvalRequest req;
      req.agent = agent;
      req.checkpoint = checkpoint;
      req.record = true;  // the replays of report.html
      run_eval(e, req);
      runs.push_back(e.eval.out);
    }
    std::vector<RunResult> results;
    for (const auto& f : find_result_files(runs)) results.push_back(load_result(f));
    const std::string markdown = render_markdown(build_report(results), default_metric_sets(results));
    std::printf("\n%s", markdown.c_str());
    // The page beside the run's folders: tables, charts and replays of the first failures.
    const std::string page =
        (std::filesystem::path(eval_root).parent_path() / "report.html").string();
    write_file_atomic(page, render_html_report(results, markdown, HtmlReportOptions{}));
    const double secs =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    std::printf("\nresults: %s/<agent>/results.json; `causaldrive report %s` prints the tables "
                "again. Selected causes: %s/causes.json. Total time %s.\n",
                eval_root.c_str(), eval_root.c_str(), cim.out_dir.c_str(),
                format_duration(secs).c_str());
    std::printf("report: %s (tables, charts and replays of the first failures; open it in a "
                "browser)\n", page.c_str());
  });
}

}  // namespace cd::cli
