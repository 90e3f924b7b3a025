#include "bench/report.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <set>
#include <sstream>

#include <nlohmann/json.hpp>

#include "core/atomic_file.hpp"
#include "core/error.hpp"

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

std::string format_cell(const std::optional<CellStats>& s, const Metric& m) {
  if (!s) return kMissingCell;
  if (s->n == 0) return kNoValue;
  const std::string fmt = "%." + std::to_string(m.decimals) + "f";
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
                             const std::string& title) {
  // Rows of cells: header first, then one per label.
  std::vector<std::vector<std::string>> rows;
  std::vector<std::string> header = {"label"};
  for (const auto& suite : table.suites)
    for (const auto& m : set.metrics) header.push_back(markdown_escape(suite) + " " + m.header);
  rows.push_back(header);
  for (const auto& label : table.labels) {
    std::vector<std::string> row = {markdown_escape(label)};
    for (const auto& suite : table.suites)
      for (const auto& m : set.metrics) row.push_back(format_cell(table.stats(label, suite, m.key), m));
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

std::string RunResult::column() const {
  return sensor == "clean" ? suite : suite + " (" + sensor + " sensor)";
}

const std::vector<FailureCondition>& failure_conditions() {
  static const std::vector<FailureCondition> conditions = {
      {"training town", "town-a", "clean"},
      {"new sensor", "town-a", "shifted"},
      {"new town", "town-b", "clean"},
  };
  return conditions;
}

const std::vector<MetricSet>& metric_sets() {
  static const std::vector<MetricSet> sets = {
      {"error",
       "Error rates (%, mean \u00b1 sd over seeds; error = collision + inertia; paper error = "
       "inertia + collisions with vehicles, seed 000's measure)",
       {{"error_rate", "error %", 100.0},
        {"inertia_rate", "inertia %", 100.0},
        {"collision_rate", "collision %", 100.0},
        {"paper_error_rate", "paper error %", 100.0},
        {"pedestrian_collision_rate", "ped. collision %", 100.0}}},
      {"outcomes",
       "Outcomes (%, mean \u00b1 sd over seeds)",
       {{"success_rate", "success %", 100.0},
        {"collision_rate", "collision %", 100.0},
        {"timeout_rate", "timeout %", 100.0}}},
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
       "MuJoCo-Image (eval --env): return per episode and the copycat R\u00b2 of a_t from "
       "a_{t-1}, policy vs its expert's data (mean \u00b1 sd over seeds)",
       {{"mean_return", "return", 1.0},
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

std::optional<CellStats> ReportTable::stats(const std::string& label, const std::string& suite,
                                            const std::string& key) const {
  auto it = cells.find({label, suite});
  if (it == cells.end()) return std::nullopt;
  std::vector<double> values;
  for (const RunResult* r : it->second) {
    auto v = r->summary.find(key);
    if (v != r->summary.end() && v->second) values.push_back(*v->second);
  }
  return mean_std(values);
}

ReportTable build_report(const std::vector<RunResult>& runs) {
  std::vector<const RunResult*> all;
  for (const RunResult& r : runs) all.push_back(&r);
  return group_runs(all, [](const RunResult& r) { return r.column(); });
}

ReportTable condition_table(const ReportTable& table, const FailureCondition& condition) {
  std::vector<const RunResult*> in;
  for (const RunResult* r : table.runs)
    if (r->town == condition.town && r->sensor == condition.sensor) in.push_back(r);
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

std::string render_markdown(const ReportTable& table, const std::vector<MetricSet>& sets) {
  std::string out;
  for (const MetricSet& set : sets) {
    if (!out.empty()) out += '\n';  // a blank line between tables
    if (!set.by_condition) {
      out += render_set_table(table, set, set.title);
      continue;
    }
    std::string names, tables;
    for (const FailureCondition& c : failure_conditions()) {
      names += (names.empty() ? "" : ", ") + c.name + " (" + c.town + ", " + c.sensor + " sensor)";
      ReportTable t = condition_table(table, c);
      if (t.labels.empty()) continue;
      if (!tables.empty()) tables += '\n';
      tables += render_set_table(t, set,
                                 set.title + ", " + c.name + " (" + c.town + ", " + c.sensor +
                                     " sensor; %, mean \u00b1 sd over seeds)");
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

}  // namespace cd
