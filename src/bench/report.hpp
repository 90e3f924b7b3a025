#pragma once
// Comparison tables over evaluation runs (`causaldrive report`): reads the results.json files
// that `causaldrive eval` writes, groups them by (label, suite and sensor), and renders one
// table per metric set (rows: labels, column groups: suites, a shifted sensor's runs in
// columns of their own) as Markdown, plus a long-format CSV. Several runs with the same
// (label, column) are repeated seeds: mean and sample standard deviation (n - 1) over them.
// The failure-mode set (seed 001 tables 7-9) is one table per condition instead: training
// town, new sensor, new town (failure_conditions()), column groups the suites without their
// town prefix (regular, dense, ...).
#include <map>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace cd {

// One results.json, reduced to what the tables need.
struct RunResult {
  std::string path;   // the file it came from
  std::string agent;
  std::string label;  // `label`, or `agent` when the file has none
  std::string suite;  // the driving suite, or a MuJoCo-Image run's env
  bool mujoco = false;  // an `eval --env` run (results.json has `env`, no `suite`)
  std::string town;             // `town`, "" when the file has none
  std::string sensor = "clean"; // `sensor` (eval.sensor), "clean" when the file has none
  // Every numeric (or null) entry of `summary`; null is std::nullopt (e.g. no start delay).
  std::map<std::string, std::optional<double>> summary;

  // The column group of the tables: the suite, with " (SENSOR sensor)" unless clean.
  std::string column() const;
};

// The results.json files under each folder (recursively, sorted by path; the folder's own one
// included), folders in the order given. A path that is itself a file is taken as is. The same
// file reached twice (overlapping folders) is listed once. Throws IoError for a folder that does
// not exist or holds no results.json.
std::vector<std::string> find_result_files(const std::vector<std::string>& run_dirs);

// Parses one results.json. Throws DataError naming the file (and the key) when it is not valid
// JSON, lacks `agent`, `suite` or `summary`, or has a rate outside [0, 1]; IoError when unreadable.
RunResult load_result(const std::string& path);

// A column of the tables: a key of results.json's `summary`.
struct Metric {
  std::string key;     // summary key, also the `metric` column of the CSV
  std::string header;  // column title in the tables
  double scale;        // table value = scale * summary value (100 for rates shown in %)
  int decimals = 1;    // in the tables
};

// A named group of metrics, one table each.
struct MetricSet {
  std::string name;   // error | outcomes | stopgo | lights | failure | lateral | return
  std::string title;  // the line printed above its table
  std::vector<Metric> metrics;
  bool by_condition = false;  // one table per failure condition (failure_conditions())
  bool in_all = true;         // part of `all` (the driving sets; `return` is MuJoCo-Image's)
};

// A condition of the failure-mode tables: the runs on `town` with sensor `sensor`.
struct FailureCondition {
  std::string name;    // training town | new sensor | new town
  std::string town;    // town-a | town-b (SPEC section 1: the training town, the new town)
  std::string sensor;  // clean | shifted
};

// In the order of seed 001's tables 7, 8 and 9. Runs in none of them (town-c, a new town with
// a shifted sensor, a custom network) are left out of the failure-mode tables only.
const std::vector<FailureCondition>& failure_conditions();

// The known sets, in the order `all` prints them.
const std::vector<MetricSet>& metric_sets();

// Parses the --metrics value: `error`, `outcomes`, `stopgo`, `lights`, `failure`, `lateral`
// (a free-steering ego), `return` (MuJoCo-Image), `all` (the driving sets but lateral), or a
// comma-separated list of them. Throws ConfigError naming the unknown value.
std::vector<MetricSet> parse_metric_sets(const std::string& spec);

// Does the run come from a free-steering ego (ego.lateral = "free")? Its summary has a lateral
// error (null in route mode, where the ego rides its lane's centre) or an off-road episode.
bool steers_freely(const RunResult& run);

// The sets of `report` without --metrics (and of quickstart's table): `return` when every run is
// MuJoCo-Image; else `all`, plus `lateral` (off-road beside the error) when a run steers freely.
std::vector<MetricSet> default_metric_sets(const std::vector<RunResult>& runs);

// Mean and sample standard deviation of one metric over the seeds of one (label, suite).
struct CellStats {
  int n = 0;                  // runs with a value (null values are left out)
  double mean = 0;            // valid when n >= 1
  std::optional<double> std;  // sample standard deviation, when n >= 2
};

// Mean and sample standard deviation (n - 1); n = 0 for an empty list.
CellStats mean_std(const std::vector<double>& values);

struct ReportTable {
  std::vector<std::string> labels;  // rows, in order of first appearance
  std::vector<std::string> suites;  // column groups (RunResult::column()), sorted by name
  // (label, column) -> the runs of it (one per seed); a pair not present is a missing cell.
  std::map<std::pair<std::string, std::string>, std::vector<const RunResult*>> cells;
  std::vector<const RunResult*> runs;  // all of them, in the order given

  // Statistics of `key` in one cell; std::nullopt when no run of label on suite exists.
  std::optional<CellStats> stats(const std::string& label, const std::string& suite,
                                 const std::string& key) const;
};

// Groups runs (kept by pointer: `runs` must outlive the table).
ReportTable build_report(const std::vector<RunResult>& runs);

// The failure-mode table of one condition: the table's runs in that condition, grouped by
// (label, suite without its "TOWN-" prefix); column groups empty, regular, dense first, then
// the others by name. No labels when no run is in the condition.
ReportTable condition_table(const ReportTable& table, const FailureCondition& condition);

// Markdown: for each set a title line ("## ..."), a blank line and the table; blank lines
// between sets. A by_condition set gives one such table per condition that has runs (title
// "SET TITLE, CONDITION (TOWN, SENSOR sensor; ...)"), or its title and one line saying that no
// run is in any condition.
// Cells: "mean ± sd" (just the mean for one seed), "–" when the label has no run on the suite,
// "n/a" when its runs have no value for the metric (null, e.g. no stop-and-go event).
std::string render_markdown(const ReportTable& table, const std::vector<MetricSet>& sets);

// Long format: header `label,suite,metric,mean,std,n`, one row per present cell and metric
// (metrics of the sets, each once), values in the units of results.json (rates as fractions),
// 12 significant digits; std empty when n < 2, mean empty when n = 0. `suite` is the column
// (RunResult::column(): a shifted sensor's runs as "SUITE (shifted sensor)"); the failure-mode
// set adds no rows of its own (its conditions are read off the suite and sensor).
std::string render_csv(const ReportTable& table, const std::vector<MetricSet>& sets);

}  // namespace cd
