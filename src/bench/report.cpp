#include "bench/report.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <set>
#include <sstream>

#include <nlohmann/json.hpp>

#include "bench/metrics.hpp"
#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "sense/camera.hpp"

namespace cd {

namespace fs = std::filesystem;

namespace {

constexpr const char* kResultsName = "results.json";
constexpr const char* kMissingCell = "\u2013";  // en dash: no run of the label on the suite
constexpr const char* kNoValue = "n/a";         // runs exist, but the metric is null in all

bool ends_with(const std::string& s, const std::string& suffix) {
  return s.size() >= suffix.size() &&
         s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

// Keys of `summary` that some table shows: a value of another type than number/null is an error.
const std::set<std::string>& shown_keys() {
  static const std::set<std::string> keys = [] {
    std::set<std::string> k;
    for (const auto& set : metric_sets())
      for (const auto& m : set.metrics) k.insert(m.key);
    return k;
  }();
  return keys;
}

std::string required_string(const nlohmann::json& doc, const std::string& key,
                            const std::string& path) {
  auto it = doc.find(key);
  if (it == doc.end())
    throw DataError(path + ": missing key '" + key +
                    "' (expected a results.json written by `causaldrive eval`)");
  if (!it->is_string() || it->get<std::string>().empty())
    throw DataError(path + ": key '" + key + "' must be a non-empty string");
  return it->get<std::string>();
}

// Display width of UTF-8 text (code points; the tables only use narrow characters).
size_t display_width(const std::string& s) {
  size_t w = 0;
  for (unsigned char c : s)
    if ((c & 0xC0) != 0x80) ++w;
  return w;
}

std::string pad(const std::string& s, size_t width, bool right_align) {
  size_t w = display_width(s);
  std::string fill(width > w ? width - w : 0, ' ');
  return right_align ? fill + s : s + fill;
}

std::string markdown_escape(const std::string& s) {
  std::string out;
  for (char c : s) {
    if (c == '|') out += "\\|";
    else if (c == '\n' || c == '\r') out += ' ';
    else out += c;
  }
  return out;
}

std::string csv_field(const std::string& s) {
  if (s.find_first_of(",\"\n\r") == std::string::npos) return s;
  std::string out = "\"";
  for (char c : s) {
    if (c == '"') out += '"';
    out += c;
  }
  return out + "\"";
}

std::string format_number(double v, const char* fmt) {
  char buf[64];
  std::snprintf(buf, sizeof buf, fmt, v);
  return buf;
}

std::string format_cell(const std::optional<CellStats>& s, const Metric& m, Spread spread) {
  if (!s) return kMissingCell;
  if (s->n == 0) return kNoValue;
  const std::string fmt = "%." + std::to_string(m.decimals) + "f";
  if (s->interval && spread == Spread::interval)
    return format_number(m.scale * s->interval->mean, fmt.c_str()) + " [" +
           format_number(m.scale * s->interval->lo, fmt.c_str()) + ", " +
           format_number(m.scale * s->interval->hi, fmt.c_str()) + "]";
  std::string text = format_number(m.scale * s->mean, fmt.c_str());
  if (s->std) {
    text += " \u00b1 ";
    text += format_number(m.scale * *s->std, fmt.c_str());
  }
  return text;
}

// Groups runs into a table by (label, column_of(run)), in the order given.
template <class ColumnOf>
ReportTable group_runs(const std::vector<const RunResult*>& runs, ColumnOf column_of) {
  ReportTable t;
  std::set<std::string> columns;
  for (const RunResult* r : runs) {
    if (std::find(t.labels.begin(), t.labels.end(), r->label) == t.labels.end())
      t.labels.push_back(r->label);
    const std::string column = column_of(*r);
    columns.insert(column);
    t.cells[{r->label, column}].push_back(r);
    t.runs.push_back(r);
  }
  t.suites.assign(columns.begin(), columns.end());
  return t;
}

// One table of `set` over `table`'s columns, under "## title".
std::string render_set_table(const ReportTable& table, const MetricSet& set,
                             const std::string& title, Spread spread) {
  // Rows of cells: header first, then one per label.
  std::vector<std::vector<std::string>> rows;
  std::vector<std::string> header = {"label"};
  for (const auto& suite : table.suites)
    for (const auto& m : set.metrics) header.push_back(markdown_escape(suite) + " " + m.header);
  rows.push_back(header);
  for (const auto& label : table.labels) {
    std::vector<std::string> row = {markdown_escape(label)};
    for (const auto& suite : table.suites)
      for (const auto& m : set.metrics)
        row.push_back(format_cell(table.stats(label, suite, m.key), m, spread));
    rows.push_back(row);
  }
  std::vector<size_t> width(header.size(), 3);
  for (const auto& row : rows)
    for (size_t c = 0; c < row.size(); ++c) width[c] = std::max(width[c], display_width(row[c]));

  auto line = [&](const std::vector<std::string>& row) {
    std::string s = "|";
    for (size_t c = 0; c < row.size(); ++c) {
      s += ' ';
      s += pad(row[c], width[c], c > 0);
      s += " |";
    }
    return s + "\n";
  };
  std::string out = "## " + title + "\n\n";
  bool any_interval = false;
  for (size_t i = 1; i < rows.size(); ++i)
    for (size_t c = 1; c < rows[i].size(); ++c)
      any_interval = any_interval || rows[i][c].find(" [") != std::string::npos;
  const bool iqm = std::any_of(set.metrics.begin(), set.metrics.end(),
                              [](const Metric& m) { return m.key == kIqmReturn; });
  if (any_interval && iqm)
    out += "IQM return: the interquartile mean over seeds x episodes [95% two-level bootstrap "
           "interval, " + std::to_string(table.resamples) + " resamples, seed " +
           std::to_string(table.bootstrap_seed) + "]; the rest mean \u00b1 sd over seeds.\n\n";
  else if (any_interval)
    out += "Rates of episodes: mean [95% interval over training seeds and their episodes]; the "
           "rest mean \u00b1 sd over seeds.\n\n";
  out += line(rows[0]);
  std::string rule = "|";
  for (size_t c = 0; c < width.size(); ++c) {
    rule += ' ';
    rule.append(c == 0 ? width[c] : width[c] - 1, '-');  // numbers are right-aligned
    rule += c == 0 ? " |" : ": |";
  }
  out += rule + "\n";
  for (size_t i = 1; i < rows.size(); ++i) out += line(rows[i]);
  return out;
}

// Column groups of the failure-mode tables: traffic levels in NoCrash order, then by name.
int traffic_rank(const std::string& column) {
  static const std::vector<std::string> order = {"empty", "regular", "dense"};
  auto it = std::find(order.begin(), order.end(), column);
  return static_cast<int>(it - order.begin());
}

}  // namespace

std::string run_column(const std::string& suite, const std::string& sensor,
                       const std::string& weather) {
  std::string column = suite;
  if (sensor != "clean") column += " (" + sensor + " sensor)";
  if (!weather.empty() && weather != kTrainWeathers) column += " (" + weather + " weather)";
  return column;
}

std::string RunResult::column() const { return run_column(suite, sensor, weather); }

bool RunResult::new_sensor() const {
  if (sensor != "clean" || weather == kHeldOutWeathers) return true;
  const CameraWeather* set = find_camera_weather(weather);  // one held-out set named
  return set && set->held_out;
}

const std::vector<FailureCondition>& failure_conditions() {
  static const std::vector<FailureCondition> conditions = {
      {"training town", "town-a", false, "clean sensor"},
      {"new sensor", "town-a", true, "shifted sensor or held-out weather"},
      {"new town", "town-b", false, "clean sensor"},
  };
  return conditions;
}

const std::vector<MetricSet>& metric_sets() {
  static const std::vector<MetricSet> sets = {
      {"error",
       "Error rates (%; error = collision + inertia; paper error = seed 000's inertia (stood "
       "the last 15 s, whatever the path) + collisions with vehicles, its measure)",
       {{"error_rate", "error %", 100.0},
        {"inertia_rate", "inertia %", 100.0},
        {"collision_rate", "collision %", 100.0},
        {"paper_error_rate", "paper error %", 100.0},
        {"pedestrian_collision_rate", "ped. collision %", 100.0}}},
      {"outcomes",
       "Outcomes (%, every class of SPEC section 14: a row sums to 100; copycat = stuck + "
       "restart stall + stopped free; runs evaluated before the taxonomy have n/a in its classes)",
       {{"success_rate", "success %", 100.0},
        {"collision_rate", "collision %", 100.0},
        {"offroad_rate", "off-road %", 100.0},
        {"stuck_rate", "stuck %", 100.0},
        {"restart_stall_rate", "restart stall %", 100.0},
        {"stopped_free_rate", "stopped free %", 100.0},
        {"blocked_rate", "blocked %", 100.0},
        {"slow_rate", "slow %", 100.0},
        {"copycat_rate", "copycat %", 100.0}}},
      {"stopgo",
       "Stop-and-go events (stall rate %, start delay s; mean \u00b1 sd over seeds)",
       {{"stall_rate", "stall %", 100.0},
        {"start_delay_median_s", "delay median s", 1.0},
        {"start_delay_p90_s", "delay p90 s", 1.0}}},
      {"lights",
       "Traffic lights (green light %: light-controlled junctions entered on green, pooled over "
       "a run's episodes; red-light violations per km; mean \u00b1 sd over seeds)",
       {{"green_light_rate", "green light %", 100.0},
        {"red_light_violations_per_km", "red / km", 1.0, 2}}},
      {"failure",
       "Failure modes",
       {{"success_rate", "success %", 100.0},
        {"collision_rate", "collision %", 100.0},
        {"time_limit_rate", "timeout %", 100.0},
        {"inertia_rate", "inertia %", 100.0}},
       true},
      {"lateral",
       "Lateral control (a free-steering ego, ego.lateral = \"free\"; off-road ends an episode "
       "and is reported beside error = collision + inertia; mean \u00b1 sd over seeds)",
       {{"offroad_rate", "off-road %", 100.0},
        {"error_rate", "error %", 100.0},
        {"wrong_way_per_km", "wrong way / km", 1.0, 2},
        {"lane_invasions_per_km", "lane invasions / km", 1.0, 2},
        {"lane_changes_per_km", "lane changes / km", 1.0, 2},
        {"mean_lateral_error_m", "lateral error m", 1.0, 2}},
       false,
       false},
      {"return",
       "MuJoCo-Image (eval --env): return per episode, its interquartile mean over seeds x "
       "episodes, and the copycat R\u00b2 of a_t from a_{t-1}, policy vs its expert's data",
       {{"mean_return", "return", 1.0},
        {kIqmReturn, "IQM return", 1.0},
        {"mean_length", "length", 1.0, 0},
        {"copycat_policy_r2", "R\u00b2 policy", 1.0, 3},
        {"copycat_expert_r2", "R\u00b2 expert", 1.0, 3}},
       false,
       false},
  };
  return sets;
}

std::vector<MetricSet> parse_metric_sets(const std::string& spec) {
  std::vector<MetricSet> out;
  std::set<std::string> taken;
  auto add = [&](const MetricSet& s) {
    if (taken.insert(s.name).second) out.push_back(s);
  };
  std::string names;
  for (const auto& s : metric_sets()) names += s.name + ", ";
  names += "all";
  std::stringstream in(spec);
  std::string item;
  bool any = false;
  while (std::getline(in, item, ',')) {
    any = true;
    if (item == "all") {
      for (const auto& s : metric_sets())
        if (s.in_all) add(s);
      continue;
    }
    auto it = std::find_if(metric_sets().begin(), metric_sets().end(),
                           [&](const MetricSet& s) { return s.name == item; });
    if (it == metric_sets().end())
      throw ConfigError("--metrics: unknown metric set '" + item + "' (choose from " + names +
                        ", or a comma-separated list)");
    add(*it);
  }
  if (!any) throw ConfigError("--metrics: empty value (choose from " + names + ")");
  return out;
}

bool steers_freely(const RunResult& run) {
  auto value = [&](const char* key) {
    auto it = run.summary.find(key);
    return it == run.summary.end() ? std::optional<double>() : it->second;
  };
  const std::optional<double> offroad = value("offroad_rate");
  return value("mean_lateral_error_m").has_value() || (offroad && *offroad > 0);
}

std::vector<MetricSet> default_metric_sets(const std::vector<RunResult>& runs) {
  if (!runs.empty() && std::all_of(runs.begin(), runs.end(), [](const RunResult& r) { return r.mujoco; }))
    return parse_metric_sets("return");
  const bool free = std::any_of(runs.begin(), runs.end(), steers_freely);
  return parse_metric_sets(free ? "all,lateral" : "all");
}

std::vector<std::string> find_result_files(const std::vector<std::string>& run_dirs) {
  std::vector<std::string> files;
  std::set<fs::path> seen;
  for (const std::string& dir : run_dirs) {
    std::error_code ec;
    fs::file_status st = fs::status(dir, ec);
    if (ec || !fs::exists(st))
      throw IoError("run folder '" + dir + "' does not exist");
    std::vector<fs::path> found;
    if (fs::is_regular_file(st)) {
      found.push_back(dir);
    } else if (fs::is_directory(st)) {
      fs::recursive_directory_iterator it(dir, fs::directory_options::skip_permission_denied, ec);
      if (ec) throw IoError("cannot list run folder '" + dir + "': " + ec.message());
      for (; it != fs::recursive_directory_iterator(); it.increment(ec)) {
        if (ec) throw IoError("cannot list run folder '" + dir + "': " + ec.message());
        if (it->path().filename() == kResultsName && it->is_regular_file(ec)) found.push_back(it->path());
      }
      if (ec) throw IoError("cannot list run folder '" + dir + "': " + ec.message());
    } else {
      throw IoError("run folder '" + dir + "' is neither a folder nor a file");
    }
    if (found.empty())
      throw IoError("no results.json under '" + dir +
                    "' (give output folders of `causaldrive eval`, or folders holding them)");
    std::sort(found.begin(), found.end());
    for (const fs::path& p : found) {
      fs::path key = fs::weakly_canonical(p, ec);
      if (ec) key = p;
      if (seen.insert(key).second) files.push_back(p.string());
    }
  }
  return files;
}

RunResult load_result(const std::string& path) {
  const std::string text = read_file_bytes(path);
  nlohmann::json doc;
  try {
    doc = nlohmann::json::parse(text);
  } catch (const nlohmann::json::parse_error& e) {
    std::string why = e.what();
    if (auto p = why.find("] "); why.rfind("[json.exception", 0) == 0 && p != std::string::npos)
      why = why.substr(p + 2);
    throw DataError(path + ": not valid JSON (" + why + ")");
  }
  if (!doc.is_object()) throw DataError(path + ": not a JSON object");

  RunResult r;
  r.path = path;
  r.agent = required_string(doc, "agent", path);
  // MuJoCo-Image runs (eval --env) name their env where driving runs name their suite.
  r.mujoco = !doc.contains("suite") && doc.contains("env");
  r.suite = required_string(doc, r.mujoco ? "env" : "suite", path);
  r.label = r.agent;
  if (auto it = doc.find("label"); it != doc.end() && !it->is_null()) {
    if (!it->is_string()) throw DataError(path + ": key 'label' must be a string");
    if (!it->get<std::string>().empty()) r.label = it->get<std::string>();
  }
  for (auto [key, field] : {std::pair<const char*, std::string*>{"town", &r.town},
                            std::pair<const char*, std::string*>{"sensor", &r.sensor}}) {
    auto it = doc.find(key);
    if (it == doc.end()) continue;
    if (!it->is_string() || it->get<std::string>().empty())
      throw DataError(path + ": key '" + key + "' must be a non-empty string");
    *field = it->get<std::string>();
  }
  if (auto it = doc.find("weather"); it != doc.end()) {
    if (!it->is_string() || it->get<std::string>().empty())
      throw DataError(path + ": key 'weather' must be a non-empty string");
    r.weather = it->get<std::string>();
  }
  if (auto eps = doc.find("episodes"); eps != doc.end() && eps->is_array()) {
    int held_out = 0, training = 0;  // episodes by their weather (files without 'weather')
    for (const nlohmann::json& e : *eps) {
      if (!e.is_object()) throw DataError(path + ": an entry of 'episodes' is not an object");
      if (auto w = e.find("weather"); w != e.end() && w->is_string() && !w->get<std::string>().empty()) {
        const CameraWeather* set = find_camera_weather(w->get<std::string>());
        if (!set)
          throw DataError(path + ": an episode's weather '" + w->get<std::string>() +
                          "' is not a camera weather set");
        ++(set->held_out ? held_out : training);
      }
      RunEpisode ep;
      ep.task = e.value("task", e.value("index", 0));
      ep.outcome = e.value("outcome", "");
      ep.collision_kind = e.value("collision_kind", "");
      ep.index = e.value("index", static_cast<int>(r.episodes.size()));
      if (auto t = e.find("taxonomy"); t != e.end() && t->is_object()) {
        ep.taxonomy = true;
        ep.paper_inertia = t->value("paper_inertia", false);
        if (auto c = t->find("last_stop_cause"); c != t->end() && c->is_string())
          ep.stop_cause = c->get<std::string>();
      }
      if (auto r = e.find("return"); r != e.end() && r->is_number()) ep.ret = r->get<double>();
      r.episodes.push_back(ep);
    }
    if (r.weather.empty() && held_out + training > 0)
      r.weather = training == 0 ? kHeldOutWeathers : held_out == 0 ? kTrainWeathers : "mixed";
  }
  auto summary = doc.find("summary");
  if (summary == doc.end())
    throw DataError(path + ": missing key 'summary' (expected a results.json written by "
                    "`causaldrive eval`)");
  if (!summary->is_object()) throw DataError(path + ": key 'summary' must be an object");
  for (const auto& [key, value] : summary->items()) {
    if (value.is_null()) {
      r.summary[key] = std::nullopt;
    } else if (value.is_number()) {
      double v = value.get<double>();
      if (ends_with(key, "_rate") && !(v >= 0.0 && v <= 1.0))
        throw DataError(path + ": summary." + key + " = " + value.dump() +
                        " is outside [0, 1] (rates are fractions)");
      r.summary[key] = v;
    } else if (shown_keys().count(key)) {
      throw DataError(path + ": summary." + key + " must be a number or null, not " +
                      value.type_name());
    }
  }
  return r;
}

namespace {
// One of the taxonomy's timeout classes (records before it said inertia or timeout).
bool ran_out_of_time(const RunEpisode& e) {
  const auto& classes = timeout_classes();
  return std::find(classes.begin(), classes.end(), e.outcome) != classes.end();
}
}  // namespace

EpisodeIndicator episode_indicator(const std::string& key) {
  static const std::map<std::string, EpisodeIndicator> indicators = {
      {"success_rate", [](const RunEpisode& e) { return e.outcome == "success"; }},
      {"collision_rate", [](const RunEpisode& e) { return e.outcome == "collision"; }},
      {"offroad_rate", [](const RunEpisode& e) { return e.outcome == "offroad"; }},
      {"stuck_rate", [](const RunEpisode& e) { return e.outcome == "stuck" || e.outcome == "inertia"; }},
      {"inertia_rate", [](const RunEpisode& e) { return e.outcome == "stuck" || e.outcome == "inertia"; }},
      {"restart_stall_rate", [](const RunEpisode& e) { return e.outcome == "restart_stall"; }},
      {"stopped_free_rate", [](const RunEpisode& e) { return e.outcome == "stopped_free"; }},
      {"blocked_rate", [](const RunEpisode& e) { return e.outcome == "blocked"; }},
      {"slow_rate", [](const RunEpisode& e) { return e.outcome == "slow"; }},
      {"copycat_rate", [](const RunEpisode& e) { return is_copycat_class(e.outcome) || e.outcome == "inertia"; }},
      {"timeout_rate",
       [](const RunEpisode& e) {
         return e.outcome == "timeout" || (ran_out_of_time(e) && e.outcome != "stuck");
       }},
      {"time_limit_rate",
       [](const RunEpisode& e) {
         return e.outcome == "timeout" || e.outcome == "inertia" || ran_out_of_time(e);
       }},
      {"error_rate",
       [](const RunEpisode& e) {
         return e.outcome == "collision" || e.outcome == "stuck" || e.outcome == "inertia";
       }},
      {"vehicle_collision_rate",
       [](const RunEpisode& e) { return e.outcome == "collision" && e.collision_kind == "vehicle"; }},
      {"pedestrian_collision_rate",
       [](const RunEpisode& e) { return e.outcome == "collision" && e.collision_kind == "pedestrian"; }},
      {"paper_inertia_rate", [](const RunEpisode& e) { return e.paper_inertia; }},
      {"paper_error_rate",
       [](const RunEpisode& e) {
         return e.paper_inertia || (e.outcome == "collision" && e.collision_kind == "vehicle");
       }},
  };
  auto it = indicators.find(key);
  return it == indicators.end() ? nullptr : it->second;
}

std::optional<SeedRuns> seed_runs(const std::vector<const RunResult*>& runs,
                                  const std::string& key) {
  const EpisodeIndicator counts = episode_indicator(key);
  if (!counts || runs.empty()) return std::nullopt;
  // Seed 000's inertia is in the taxonomy's fields: older records cannot give it per episode.
  const bool needs_taxonomy = key.rfind("paper_", 0) == 0;
  SeedRuns seeds;
  for (const RunResult* r : runs) {
    if (r->mujoco || r->episodes.empty()) return std::nullopt;
    // A rate the run's summary does not hold (a class its records predate) gets no interval.
    if (auto v = r->summary.find(key); v == r->summary.end() || !v->second) return std::nullopt;
    // The episodes must be the ones its summary counts.
    auto counted = r->summary.find("episodes");
    if (counted == r->summary.end() || !counted->second ||
        *counted->second != static_cast<double>(r->episodes.size()))
      return std::nullopt;
    std::map<int, std::pair<double, int>> by_task;  // task -> (count, trials)
    for (const RunEpisode& e : r->episodes) {
      if (e.outcome.empty() || e.outcome == "infrastructure_failure") return std::nullopt;
      if (needs_taxonomy && !e.taxonomy) return std::nullopt;
      auto& [hits, trials] = by_task[e.task];
      hits += counts(e) ? 1.0 : 0.0;
      ++trials;
    }
    SeedOutcomes seed;
    seed.trials = by_task.begin()->second.second;
    for (const auto& [task, ht] : by_task) {
      if (ht.second != seed.trials) return std::nullopt;
      seed.per_task.push_back(ht.first / ht.second);
    }
    if (!seeds.empty() && seeds.front().per_task.size() != seed.per_task.size())
      return std::nullopt;
    seeds.push_back(std::move(seed));
  }
  return seeds;
}

CellStats mean_std(const std::vector<double>& values) {
  CellStats s;
  s.n = static_cast<int>(values.size());
  if (s.n == 0) return s;
  double sum = 0;
  for (double v : values) sum += v;
  s.mean = sum / s.n;
  if (s.n >= 2) {
    double ss = 0;
    for (double v : values) ss += (v - s.mean) * (v - s.mean);
    s.std = std::sqrt(ss / (s.n - 1));
  }
  return s;
}

namespace {

// A MuJoCo-Image cell's returns, one list per run (training seed); nullopt when a run does not
// keep all its episodes.
std::optional<std::vector<std::vector<double>>> returns_by_seed(
    const std::vector<const RunResult*>& runs) {
  std::vector<std::vector<double>> returns;
  for (const RunResult* r : runs) {
    auto counted = r->summary.find("episodes");
    if (!r->mujoco || r->episodes.empty() || counted == r->summary.end() || !counted->second ||
        *counted->second != static_cast<double>(r->episodes.size()))
      return std::nullopt;
    std::vector<double>& seed = returns.emplace_back();
    for (const RunEpisode& e : r->episodes) seed.push_back(e.ret);
  }
  return returns;
}

}  // namespace

std::optional<CellStats> ReportTable::stats(const std::string& label, const std::string& suite,
                                            const std::string& key) const {
  auto it = cells.find({label, suite});
  if (it == cells.end()) return std::nullopt;
  if (key == kIqmReturn) {
    const std::optional<std::vector<std::vector<double>>> by_seed = returns_by_seed(it->second);
    if (!by_seed) return CellStats{};
    const std::vector<std::vector<double>>& returns = *by_seed;
    const IqmInterval q = iqm_interval(returns, bootstrap_seed, resamples);
    CellStats stats;
    stats.n = static_cast<int>(returns.size());
    stats.mean = q.iqm;
    Interval in;
    in.mean = q.iqm;
    in.lo = q.lo;
    in.hi = q.hi;
    in.seeds = stats.n;
    for (const auto& seed : returns) in.episodes += static_cast<long>(seed.size());
    stats.interval = in;
    return stats;
  }
  std::vector<double> values;
  for (const RunResult* r : it->second) {
    auto v = r->summary.find(key);
    if (v != r->summary.end() && v->second) values.push_back(*v->second);
  }
  CellStats stats = mean_std(values);
  if (std::optional<SeedRuns> seeds = seed_runs(it->second, key))
    stats.interval = rate_interval(*seeds);
  return stats;
}

ReportTable build_report(const std::vector<RunResult>& runs) {
  std::vector<const RunResult*> all;
  for (const RunResult& r : runs) all.push_back(&r);
  return group_runs(all, [](const RunResult& r) { return r.column(); });
}

ReportTable condition_table(const ReportTable& table, const FailureCondition& condition) {
  std::vector<const RunResult*> in;
  for (const RunResult* r : table.runs)
    if (r->town == condition.town && r->new_sensor() == condition.new_sensor) in.push_back(r);
  ReportTable t = group_runs(in, [](const RunResult& r) {
    const std::string prefix = r.town + "-";
    return r.suite.size() > prefix.size() && r.suite.compare(0, prefix.size(), prefix) == 0
               ? r.suite.substr(prefix.size())
               : r.suite;
  });
  std::stable_sort(t.suites.begin(), t.suites.end(), [](const std::string& a, const std::string& b) {
    return traffic_rank(a) < traffic_rank(b);
  });
  return t;
}

std::string render_markdown(const ReportTable& table, const std::vector<MetricSet>& sets,
                            Spread spread) {
  std::string out;
  for (const MetricSet& set : sets) {
    if (!out.empty()) out += '\n';  // a blank line between tables
    if (!set.by_condition) {
      out += render_set_table(table, set, set.title, spread);
      continue;
    }
    std::string names, tables;
    for (const FailureCondition& c : failure_conditions()) {
      names += (names.empty() ? "" : ", ") + c.name + " (" + c.town + ", " + c.sensor + ")";
      ReportTable t = condition_table(table, c);
      if (t.labels.empty()) continue;
      if (!tables.empty()) tables += '\n';
      tables += render_set_table(t, set,
                                 set.title + ", " + c.name + " (" + c.town + ", " + c.sensor +
                                     "; %, mean \u00b1 sd over seeds)",
                                 spread);
    }
    out += tables.empty() ? "## " + set.title + "\n\nno run in any condition: " + names + "\n"
                          : tables;
  }
  return out;
}

std::string render_csv(const ReportTable& table, const std::vector<MetricSet>& sets) {
  std::vector<std::string> keys;
  for (const MetricSet& set : sets)
    for (const Metric& m : set.metrics)
      if (std::find(keys.begin(), keys.end(), m.key) == keys.end()) keys.push_back(m.key);
  std::string out = "label,suite,metric,mean,std,n\n";
  for (const auto& label : table.labels)
    for (const auto& suite : table.suites)
      for (const auto& key : keys) {
        std::optional<CellStats> s = table.stats(label, suite, key);
        if (!s) continue;  // no run of this label on this suite
        out += csv_field(label) + "," + csv_field(suite) + "," + key + ",";
        if (s->n > 0) out += format_number(s->mean, "%.12g");
        out += ",";
        if (s->std) out += format_number(*s->std, "%.12g");
        out += ',';
        out += std::to_string(s->n);
        out += '\n';
      }
  return out;
}

namespace {

// The k-th run of `label` in each column where it has episodes, as seeds x tasks of `key`.
std::map<std::string, SeedRuns> runs_by_column(const ReportTable& table, const std::string& label,
                                               const std::string& key) {
  std::map<std::string, SeedRuns> out;
  for (const std::string& column : table.suites) {
    auto it = table.cells.find({label, column});
    if (it == table.cells.end()) continue;
    if (std::optional<SeedRuns> seeds = seed_runs(it->second, key)) out[column] = *seeds;
  }
  return out;
}

std::string pct(double v) { return format_number(100.0 * v, "%.1f"); }

// A comparison's verdict as the table shows it: marked interim where a side had one seed.
std::string verdict_cell(const Comparison& c) {
  return verdict_text(c.verdict) + (c.episode_only ? " (one seed: interim)" : "");
}

nlohmann::json comparison_json(const Comparison& c) {
  return {{"difference", c.difference}, {"lo", c.lo},   {"hi", c.hi},
          {"p_improvement", c.p_improvement}, {"verdict", verdict_text(c.verdict)},
          {"episode_only", c.episode_only}};
}

// --compare with iqm_return (MuJoCo-Image): per environment, A's IQM return less B's with its
// bootstrap interval (bench/intervals: compare_iqm); no row over environments, whose returns
// have different scales.
ComparisonReport render_iqm_comparison(const ReportTable& table, const std::string& a,
                                       const std::string& b) {
  std::string md = "## " + a + " vs " + b + ": IQM return (A - B, 95% two-level bootstrap "
                   "interval, " + std::to_string(table.resamples) + " resamples, seed " +
                   std::to_string(table.bootstrap_seed) + "; P(A > B) over seed pairs; higher is "
                   "better)\n\n| environment | A | B | A - B [95%] | P(A > B) | verdict |\n"
                   "|---|---:|---:|---:|---:|---|\n";
  nlohmann::json conditions = nlohmann::json::array();
  for (const std::string& column : table.suites) {
    auto ia = table.cells.find({a, column}), ib = table.cells.find({b, column});
    if (ia == table.cells.end() || ib == table.cells.end()) continue;
    const auto ra = returns_by_seed(ia->second), rb = returns_by_seed(ib->second);
    if (!ra || !rb) continue;
    const IqmComparison c = compare_iqm(*ra, *rb, table.bootstrap_seed, table.resamples);
    auto num = [](double v) { return format_number(v, "%.1f"); };
    md += "| " + column + " | " + num(c.a) + " | " + num(c.b) + " | " + num(c.difference) +
          " [" + num(c.lo) + ", " + num(c.hi) + "] | " + format_number(c.p_improvement, "%.2f") +
          " | " + verdict_text(c.verdict) + " |\n";
    conditions.push_back({{"condition", column}, {"a", c.a}, {"b", c.b},
                          {"difference", c.difference}, {"lo", c.lo}, {"hi", c.hi},
                          {"p_improvement", c.p_improvement},
                          {"verdict", verdict_text(c.verdict)},
                          {"seeds_a", static_cast<int>(ra->size())},
                          {"seeds_b", static_cast<int>(rb->size())}});
  }
  if (conditions.empty())
    throw ConfigError("--compare: " + a + " and " + b + " share no MuJoCo-Image environment "
                      "whose runs keep their episodes");
  const nlohmann::json out = {{"a", a}, {"b", b}, {"metric", kIqmReturn},
                              {"higher_is_better", true}, {"conditions", conditions}};
  return {md, out.dump()};
}

}  // namespace

ComparisonReport render_comparison(const ReportTable& table, const std::string& a,
                                   const std::string& b, const std::string& key) {
  for (const std::string& label : {a, b})
    if (std::find(table.labels.begin(), table.labels.end(), label) == table.labels.end())
      throw ConfigError("--compare: no run is labelled '" + label + "' (labels: " +
                        [&] {
                          std::string all;
                          for (const auto& l : table.labels) all += (all.empty() ? "" : ", ") + l;
                          return all;
                        }() + ")");
  if (key == kIqmReturn) return render_iqm_comparison(table, a, b);
  if (!episode_indicator(key))
    throw ConfigError("--compare-metric: '" + key + "' is not a share of episodes (e.g. "
                      "success_rate, collision_rate, copycat_rate) or iqm_return");
  const auto ra = runs_by_column(table, a, key), rb = runs_by_column(table, b, key);
  std::vector<SeedRuns> all_a, all_b;
  bool interim = false;  // a condition where a side had one seed
  // Success is the one rate where more is better; for the failure rates a lower rate wins.
  const bool higher_better = key == "success_rate";
  auto judged = [higher_better](Comparison c) {
    if (!higher_better && c.verdict != Verdict::not_resolved)
      c.verdict = c.verdict == Verdict::a_better ? Verdict::b_better : Verdict::a_better;
    return c;
  };
  std::string md = "## " + a + " vs " + b + ": " + key + " (A - B in points, paired 95% "
                   "interval; P(A > B) as rliable, the chance that A's rate is the higher; " +
                   (higher_better ? "higher" : "lower") + " is better)\n\n| condition | A | B | "
                   "A - B [95%] | P(A > B) | verdict |\n|---|---:|---:|---:|---:|---|\n";
  nlohmann::json conditions = nlohmann::json::array();
  for (const auto& [column, sa] : ra) {
    auto jt = rb.find(column);
    if (jt == rb.end() || sa.front().per_task.size() != jt->second.front().per_task.size())
      continue;
    const Comparison c = judged(compare(sa, jt->second));
    interim = interim || c.episode_only;
    const Interval ia = rate_interval(sa), ib = rate_interval(jt->second);
    md += "| " + column + " | " + pct(ia.mean) + " | " + pct(ib.mean) + " | " +
          pct(c.difference) + " [" + pct(c.lo) + ", " + pct(c.hi) + "] | " +
          format_number(c.p_improvement, "%.2f") + " | " + verdict_cell(c) + " |\n";
    nlohmann::json j = comparison_json(c);
    j["condition"] = column;
    j["a"] = ia.mean;
    j["b"] = ib.mean;
    j["seeds_a"] = static_cast<int>(sa.size());
    j["seeds_b"] = static_cast<int>(jt->second.size());
    conditions.push_back(j);
    all_a.push_back(sa);
    all_b.push_back(jt->second);
  }
  if (all_a.empty())
    throw ConfigError("--compare: " + a + " and " + b + " share no condition whose runs hold "
                      "their episodes on the same tasks");
  nlohmann::json out = {{"a", a}, {"b", b}, {"metric", key}, {"higher_is_better", higher_better},
                        {"conditions", conditions}};
  // Over conditions: only when each label has as many seeds in every condition.
  bool same_seeds = true;
  for (size_t k = 1; k < all_a.size(); ++k)
    same_seeds = same_seeds && all_a[k].size() == all_a[0].size() &&
                 all_b[k].size() == all_b[0].size();
  if (all_a.size() > 1 && same_seeds) {
    const Comparison c = judged(compare(all_a, all_b));
    md += "| over " + std::to_string(all_a.size()) + " conditions | | | " + pct(c.difference) +
          " [" + pct(c.lo) + ", " + pct(c.hi) + "] | " + format_number(c.p_improvement, "%.2f") +
          " | " + verdict_cell(c) + " |\n";
    out["over_conditions"] = comparison_json(c);
  } else if (all_a.size() > 1) {
    md += "\n(no row over conditions: a label has different seed counts across them)\n";
  }
  if (interim)
    md += "\n(one seed: interim): a side has one training seed, so its interval counts the "
          "episodes' noise alone and says nothing of another training of the same method.\n";
  return {md, out.dump()};
}

ComparisonReport render_power(const ReportTable& table, const std::string& key, double delta) {
  if (!episode_indicator(key))
    throw ConfigError("--power: '" + key + "' is not a share of episodes");
  if (!(delta > 0 && delta < 100))
    throw ConfigError("--delta must be a number of points in (0, 100)");
  std::string md = "## Power: " + key + ", to resolve " + format_number(delta, "%.1f") +
                   " points (alpha 0.05 two-sided, 80% power)\n\n| label | condition | seeds | "
                   "episodes/seed | seed sd | episode sd | half-width now | difference "
                   "half-width now | seeds needed | seeds needed at 4x tasks |\n"
                   "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|\n";
  nlohmann::json cells = nlohmann::json::array();
  bool one_seed = false;
  for (const std::string& label : table.labels)
    for (const auto& [column, seeds] : runs_by_column(table, label, key)) {
      const VarianceComponents v = variance_components(seeds);
      const PowerPlan p = power(v, delta / 100.0);
      // One seed shows no spread between seeds: its plan counts the episodes' noise alone, so
      // the seeds it needs are a lower bound and its seed sd is unknown, not 0.
      const bool known = v.seeds > 1;
      one_seed = one_seed || !known;
      const std::string at_least = known ? "" : "\u2265 ";
      md += "| " + label + " | " + column + " | " + std::to_string(v.seeds) + " | " +
            format_number(v.episodes_per_seed, "%.0f") + " | " +
            (known ? pct(std::sqrt(v.seed_variance)) : "n/a") + " | " +
            pct(std::sqrt(v.episode_variance)) + " | " + pct(p.rate_half_width) + " | " +
            pct(p.difference_half_width) + " | " + at_least + std::to_string(p.seeds_needed) +
            " | " + at_least + std::to_string(p.seeds_needed_4x_tasks) + " |\n";
      cells.push_back({{"label", label},
                       {"condition", column},
                       {"seeds", v.seeds},
                       {"episodes_per_seed", v.episodes_per_seed},
                       {"seed_variance_known", known},
                       {"seed_variance", v.seed_variance},
                       {"episode_variance", v.episode_variance},
                       {"rate_half_width", p.rate_half_width},
                       {"difference_half_width", p.difference_half_width},
                       {"seeds_needed", p.seeds_needed},
                       {"seeds_needed_4x_tasks", p.seeds_needed_4x_tasks}});
    }
  if (cells.empty()) md += "\n(no run holds its episodes: nothing to plan from)\n";
  if (one_seed)
    md += "\nn/a, \u2265: a row of one seed has no seed sd to measure; its half-widths and the "
          "seeds it needs count the episodes' noise alone, so the seeds needed are at least "
          "those shown.\n";
  return {md, nlohmann::json({{"metric", key}, {"delta_points", delta}, {"cells", cells}}).dump()};
}

std::string render_json_cells(const ReportTable& table, const std::vector<MetricSet>& sets) {
  nlohmann::json cells = nlohmann::json::array();
  std::set<std::string> seen;
  for (const MetricSet& set : sets)
    for (const Metric& m : set.metrics) {
      if (!seen.insert(m.key).second) continue;
      for (const auto& label : table.labels)
        for (const auto& column : table.suites) {
          std::optional<CellStats> s = table.stats(label, column, m.key);
          if (!s) continue;
          nlohmann::json c = {{"label", label}, {"column", column}, {"metric", m.key},
                              {"n", s->n}};
          c["mean"] = s->n > 0 ? nlohmann::json(s->mean) : nlohmann::json();
          c["std"] = s->std ? nlohmann::json(*s->std) : nlohmann::json();
          if (s->interval) {
            c["lo"] = s->interval->lo;
            c["hi"] = s->interval->hi;
            c["seeds"] = s->interval->seeds;
            c["episodes"] = s->interval->episodes;
          }
          cells.push_back(c);
        }
    }
  return nlohmann::json({{"cells", cells}}).dump();
}

}  // namespace cd
