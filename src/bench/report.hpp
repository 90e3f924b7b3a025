#pragma once
// Comparison tables over evaluation runs (`causaldrive report`): reads the results.json files
// that `causaldrive eval` writes, groups them by (label, suite, sensor and camera weather), and
// renders one table per metric set (rows: labels, column groups: suites, a shifted sensor's or
// a held-out weather's runs in columns of their own) as Markdown, plus a long-format CSV.
// Several runs with the same (label, column) are repeated seeds: mean and sample standard deviation (n - 1) over them.
// The failure-mode set (seed 001 tables 7-9) is one table per condition instead: training
// town, new sensor, new town (failure_conditions()), column groups the suites without their
// town prefix (regular, dense, ...).
#include <map>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "bench/intervals.hpp"

namespace cd {

// The return set's metric that is computed from the episodes, not read from the summary.
inline constexpr const char* kIqmReturn = "iqm_return";

// One episode of a run, as the intervals need it: its task, and its outcome (driving) or
// return (MuJoCo-Image).
struct RunEpisode {
  int task = 0;
  std::string outcome, collision_kind;
  bool paper_inertia = false;
  bool taxonomy = false;  // the record has the taxonomy's fields (paper_inertia among them)
  int index = 0;          // the episode's index in its run (its recording's number)
  std::string stop_cause;  // taxonomy.last_stop_cause: what held the path when it last stopped
  double ret = 0;
};

// One results.json, reduced to what the tables need.
struct RunResult {
  std::string path;   // the file it came from
  std::string agent;
  std::string label;  // `label`, or `agent` when the file has none
  std::string suite;  // the driving suite, or a MuJoCo-Image run's env
  bool mujoco = false;  // an `eval --env` run (results.json has `env`, no `suite`)
  std::string town;             // `town`, "" when the file has none
  std::string sensor = "clean"; // `sensor` (eval.sensor), "clean" when the file has none
  // The camera's weather (sense.camera.weather: "train", "held-out" or a set's name); "" for
  // the BEV. Files written before eval recorded it: read off the episodes' weathers ("held-out"
  // when every one is a held-out set, "train" when none is).
  std::string weather;
  // Every numeric (or null) entry of `summary`; null is std::nullopt (e.g. no start delay).
  std::map<std::string, std::optional<double>> summary;
  std::vector<RunEpisode> episodes;  // `episodes`, when the file has them

  // The column group of the tables: run_column() of its suite, sensor and weather.
  std::string column() const;
  // A new sensor condition (seed 001's table 8): a shifted sensor, or a held-out camera weather
  // (the pool or one of its sets; a training set named alone is no new sensor).
  bool new_sensor() const;
};

// The column group of a run: the suite, with " (SENSOR sensor)" unless the sensor is clean and
// " (WEATHER weather)" for a camera weather other than the training pool ("train").
std::string run_column(const std::string& suite, const std::string& sensor,
                       const std::string& weather);

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

// A condition of the failure-mode tables: the runs on `town` with (or without) a new sensor
// (RunResult::new_sensor()).
struct FailureCondition {
  std::string name;    // training town | new sensor | new town
  std::string town;    // town-a | town-b (SPEC section 1: the training town, the new town)
  bool new_sensor = false;
  std::string sensor;  // how the headings name it: "clean sensor", "shifted sensor or ..."
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

// Mean and sample standard deviation of one metric over the seeds of one (label, suite), and
// the rate's 95% interval over seeds and episodes (bench/intervals.hpp: rate_interval) when
// the metric is a share of episodes (episode_indicator) and every run of the cell has its
// episodes (as many as its summary counts) on the same tasks, the same trials each, none an
// infrastructure failure.
// iqm_return (MuJoCo-Image): the interquartile mean of the returns over seeds x episodes, in
// `mean` and in `interval` with its 95% two-level bootstrap interval (bench/intervals.hpp:
// iqm_interval; the table's bootstrap_seed and resamples), where every run of the cell lists its
// episodes' returns; n/a otherwise.
struct CellStats {
  int n = 0;                  // runs with a value (null values are left out)
  double mean = 0;            // valid when n >= 1
  std::optional<double> std;  // sample standard deviation, when n >= 2
  std::optional<Interval> interval;
};

// Whether an episode counts for a rate of `summary` (success_rate: its outcome is success, ...),
// or null for a metric that is not a share of episodes (stall_rate is per event, green lights
// per passage, the rest are not rates).
using EpisodeIndicator = bool (*)(const RunEpisode&);
EpisodeIndicator episode_indicator(const std::string& key);

// The runs of one cell as seeds x tasks of `key`'s indicator; null when the intervals cannot be
// had (see CellStats).
std::optional<SeedRuns> seed_runs(const std::vector<const RunResult*>& runs,
                                  const std::string& key);

// Mean and sample standard deviation (n - 1); n = 0 for an empty list.
CellStats mean_std(const std::vector<double>& values);

struct ReportTable {
  std::vector<std::string> labels;  // rows, in order of first appearance
  std::vector<std::string> suites;  // column groups (RunResult::column()), sorted by name
  // (label, column) -> the runs of it (one per seed); a pair not present is a missing cell.
  std::map<std::pair<std::string, std::string>, std::vector<const RunResult*>> cells;
  std::vector<const RunResult*> runs;  // all of them, in the order given
  // iqm_return's two-level bootstrap (report --bootstrap-seed, --resamples).
  uint64_t bootstrap_seed = 0;
  int resamples = 10000;

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
// Cells: "mean [lo, hi]", the rate's 95% interval, where CellStats has one; else (and with
// spread "sd") "mean ± sd" (just the mean for one seed); "–" when the label has no run on the
// suite, "n/a" when its runs have no value for the metric (null, e.g. no stop-and-go event).
enum class Spread { interval, sd };
std::string render_markdown(const ReportTable& table, const std::vector<MetricSet>& sets,
                            Spread spread = Spread::interval);

// `report --compare A B`: A - B in `key` (a rate) per column where both labels have runs with
// episodes, and over those columns (the k-th run of a label in each column, in path order, is
// its k-th training seed), with the paired 95% interval, P(A > B) and the verdict
// (bench/intervals.hpp: compare). The verdict names the better label: the higher rate for
// success_rate, the lower one for every failure rate (collision, error, copycat, ...).
// With iqm_return (MuJoCo-Image): per environment, A's IQM return less B's with its two-level
// bootstrap interval (bench/intervals.hpp: compare_iqm, the table's bootstrap_seed and
// resamples), no row over environments. Markdown, and the same as JSON. Throws ConfigError for
// a label without runs, a key that is neither a rate nor iqm_return, or no column where both
// can be compared.
struct ComparisonReport {
  std::string markdown;
  std::string json;  // one JSON object
};
ComparisonReport render_comparison(const ReportTable& table, const std::string& a,
                                   const std::string& b, const std::string& key);

// `report --power`: per cell with episodes, for `key`, the variance components, the half-width
// reached and the seeds per method needed to resolve `delta` (rate units) at these and at 4x
// the tasks (bench/intervals.hpp: power). Markdown and JSON.
ComparisonReport render_power(const ReportTable& table, const std::string& key, double delta);

// Every cell of `sets` as one JSON object: {"cells": [{label, column, metric, mean, std, n,
// lo, hi, seeds, episodes}, ...]} (lo/hi/seeds/episodes only where there is an interval).
std::string render_json_cells(const ReportTable& table, const std::vector<MetricSet>& sets);

// Long format: header `label,suite,metric,mean,std,n`, one row per present cell and metric
// (metrics of the sets, each once), values in the units of results.json (rates as fractions),
// 12 significant digits; std empty when n < 2, mean empty when n = 0. `suite` is the column
// (RunResult::column(): a shifted sensor's runs as "SUITE (shifted sensor)"); the failure-mode
// set adds no rows of its own (its conditions are read off the suite and sensor).
std::string render_csv(const ReportTable& table, const std::vector<MetricSet>& sets);

}  // namespace cd
