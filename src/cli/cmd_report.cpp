// `causaldrive report RUN_DIR... [--metrics SETS] [--csv FILE] [--markdown FILE]`: comparison
// tables over evaluation runs (see bench/report.hpp).
#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "bench/html_report.hpp"
#include "bench/report.hpp"
#include "cli/commands.hpp"
#include "core/atomic_file.hpp"
#include "core/error.hpp"

namespace cd::cli {

namespace {

struct ReportArgs {
  std::vector<std::string> run_dirs;
  std::string metrics = "all", csv, markdown, html;
  std::vector<int> episodes;
  int replay_frames = 300;
  int max_replays = 10;
  std::string spread = "interval";
  std::vector<std::string> compare;
  std::string compare_metric = "success_rate";
  bool power = false;
  double delta = 10.0;
  bool json = false;
  uint64_t bootstrap_seed = 0;
  int resamples = 10000;
};

// write_file_atomic, with filesystem errors (e.g. a parent that is a file) as IoError.
void write_output(const std::string& option, const std::string& path, const std::string& text) {
  try {
    write_file_atomic(path, text);
  } catch (const std::filesystem::filesystem_error& e) {
    throw IoError(option + ": cannot write " + path + ": " + e.code().message());
  }
}

}  // namespace

void add_report(CLI::App& app) {
  auto args = std::make_shared<ReportArgs>();
  CLI::App* sub = app.add_subcommand(
      "report", "comparison tables (rates with 95% intervals over seeds and episodes, or mean ± "
                "sd) from evaluation runs' results.json");
  sub->add_option("RUN_DIR", args->run_dirs,
                  "evaluation output folders holding results.json, or folders under which they "
                  "lie (searched recursively)");
  sub->add_option("--metrics,-m", args->metrics,
                  "error | outcomes | stopgo | lights | failure | lateral | return | all, or a "
                  "comma-separated list (default: all, plus lateral when a run steers freely, or "
                  "return when every run is MuJoCo-Image); lateral: off-road beside the error, "
                  "wrong way, lane invasions and lateral error of a free-steering ego; "
                  "return: return and copycat R2 of MuJoCo-Image runs (eval --env); failure: seed 001's failure-mode tables, one per "
                  "condition (training town, new sensor, new town)")
      ->type_name("SETS");
  sub->add_option("--csv", args->csv, "also write a long-format CSV (label,suite,metric,mean,std,n)")
      ->type_name("FILE");
  sub->add_option("--markdown", args->markdown, "also write the printed Markdown to this file")
      ->type_name("FILE");
  sub->add_option("--html", args->html,
                  "also write one self-contained HTML page: the tables, charts of success / "
                  "collision / copycat per agent and suite, and replays of episodes recorded by "
                  "`eval --record`")
      ->type_name("FILE");
  sub->add_option("--episodes", args->episodes,
                  "with --html: replay these episode indices of every run (default: the first "
                  "collision, copycat class and off-road episode of each run)")
      ->delimiter(',')
      ->type_name("I,J,...");
  sub->add_option("--replay-frames", args->replay_frames,
                  "with --html: frames per replay at most; a longer episode shows every k-th step")
      ->check(CLI::PositiveNumber);
  sub->add_option("--max-replays", args->max_replays,
                  "with --html: replays on the page at most, in the order of the runs (default 10)")
      ->check(CLI::PositiveNumber);
  sub->add_option("--spread", args->spread,
                  "interval: a rate as 'mean [lo, hi]', its 95% interval over seeds and "
                  "episodes, where the runs hold their episodes (default); sd: 'mean ± sd' over "
                  "seeds, as before")
      ->check(CLI::IsMember({"interval", "sd"}));
  sub->add_option("--compare", args->compare,
                  "A B: A - B per condition and over conditions, with its paired 95% interval, "
                  "P(A > B) and a verdict (labels as in the tables)")
      ->expected(2)
      ->type_name("A B");
  sub->add_option("--compare-metric", args->compare_metric,
                  "the rate --compare and --power use (default success_rate); --compare also takes "
                  "iqm_return (MuJoCo-Image)")
      ->type_name("KEY");
  sub->add_flag("--power", args->power,
                "per label and condition: the half-width reached and the seeds needed to "
                "resolve --delta points, from the observed seed and episode variance");
  sub->add_option("--delta", args->delta, "points --power plans for (default 10)")
      ->type_name("D");
  sub->add_option("--bootstrap-seed", args->bootstrap_seed,
                  "seed of the bootstrap behind MuJoCo-Image's IQM interval (default 0): same "
                  "runs and seed, same bytes")
      ->type_name("N");
  sub->add_option("--resamples", args->resamples,
                  "bootstrap resamples of the IQM interval (default 10000)")
      ->type_name("N");
  sub->add_flag("--json", args->json,
                "print one JSON object (cells with their intervals, and --compare / --power) "
                "instead of the Markdown");
  sub->callback([args] {
    // Validated here rather than by CLI11 so that every user error is one line and exit code 1.
    std::vector<MetricSet> sets = parse_metric_sets(args->metrics);
    const bool default_sets = args->metrics == "all";
    if (args->run_dirs.empty())
      throw ConfigError("report: give at least one RUN_DIR (an output folder of `causaldrive "
                        "eval`, or a folder holding several)");
    std::vector<RunResult> runs;
    for (const std::string& file : find_result_files(args->run_dirs))
      runs.push_back(load_result(file));
    // No --metrics: the driving sets (with lateral control when a run steers freely), or
    // MuJoCo-Image's table.
    if (default_sets) sets = default_metric_sets(runs);
    if (args->resamples < 1) throw ConfigError("--resamples must be >= 1");
    ReportTable table = build_report(runs);
    table.bootstrap_seed = args->bootstrap_seed;
    table.resamples = args->resamples;
    const Spread spread = args->spread == "sd" ? Spread::sd : Spread::interval;
    std::string markdown = render_markdown(table, sets, spread);
    nlohmann::json extra = nlohmann::json::object();
    if (!args->compare.empty()) {
      const ComparisonReport c =
          render_comparison(table, args->compare[0], args->compare[1], args->compare_metric);
      markdown += "\n" + c.markdown;
      extra["compare"] = nlohmann::json::parse(c.json);
    }
    if (args->power) {
      const ComparisonReport p = render_power(table, args->compare_metric, args->delta);
      markdown += "\n" + p.markdown;
      extra["power"] = nlohmann::json::parse(p.json);
    }
    if (!args->csv.empty()) write_output("--csv", args->csv, render_csv(table, sets));
    if (!args->markdown.empty()) write_output("--markdown", args->markdown, markdown);
    if (!args->html.empty()) {
      HtmlReportOptions o;
      o.episodes = args->episodes;
      o.max_frames = args->replay_frames;
      o.max_replays = args->max_replays;
      o.bootstrap_seed = args->bootstrap_seed;
      o.resamples = args->resamples;
      write_output("--html", args->html, render_html_report(runs, markdown, o));
    } else if (!args->episodes.empty()) {
      throw ConfigError("--episodes chooses the replays of --html; give --html FILE");
    }
    if (args->json) {
      nlohmann::json out = nlohmann::json::parse(render_json_cells(table, sets));
      out.update(extra);
      const std::string text = out.dump(1) + "\n";
      std::fwrite(text.data(), 1, text.size(), stdout);
    } else {
      std::fwrite(markdown.data(), 1, markdown.size(), stdout);
    }
    std::fflush(stdout);
  });
}

}  // namespace cd::cli
