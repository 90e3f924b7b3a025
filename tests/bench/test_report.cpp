// `causaldrive report`: comparison tables over hand-made results.json files (mean and sample
// standard deviation over seeds, missing cells, row and column order, folder discovery) and its
// error paths (exit code 1, one stderr line naming the file and key).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <sstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "../support/test_support.hpp"
#include "bench/intervals.hpp"
#include "bench/report.hpp"
#include "core/error.hpp"

namespace cd {
namespace {

using test::CommandResult;
using test::TempDir;
namespace fs = std::filesystem;

const std::string kDash = "\u2013";

bool has(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

// A results.json like `causaldrive eval` writes; `summary` entries override the defaults.
nlohmann::json results(const std::string& agent, const std::string& suite,
                       const nlohmann::json& summary = nlohmann::json::object(),
                       const std::string& label = "") {
  nlohmann::json s = {{"episodes", 75},          {"infrastructure_failures", 0},
                      {"success_rate", 0.9},     {"collision_rate", 0.04},
                      {"inertia_rate", 0.02},    {"timeout_rate", 0.04},
                      {"time_limit_rate", 0.06}, {"error_rate", 0.06},      {"stop_go_events", 31},
                      {"stalls", 2},             {"stall_rate", 0.0645},
                      {"start_delay_median_s", 1.3}, {"start_delay_p90_s", 2.9},
                      {"red_light_violations_per_km", 0.1}, {"route_completion", 0.93},
                      {"mean_speed", 5.1}};
  for (const auto& [k, v] : summary.items()) s[k] = v;
  nlohmann::json j = {{"agent", agent},
                      {"suite", suite},
                      {"town", "town-a"},
                      {"traffic", "regular"},
                      {"trials", 3},
                      {"seed", 0},
                      {"episodes", nlohmann::json::array({{{"task", 0}, {"trial", 0},
                                                           {"outcome", "success"}}})},
                      {"summary", s}};
  if (!label.empty()) j["label"] = label;
  return j;
}

// Writes `j` as DIR/results.json, creating DIR.
void put(const std::string& dir, const nlohmann::json& j) {
  fs::create_directories(dir);
  test::write_text(dir + "/results.json", j.dump(2));
}

std::vector<std::string> report_lines(const std::string& csv) { return test::split_lines(csv); }

// The table line (Markdown row) of `label` under the title starting with `title`.
std::string table_row(const std::string& markdown, const std::string& title,
                      const std::string& label) {
  bool in = false;
  for (const std::string& line : test::split_lines(markdown)) {
    if (test::starts_with(line, "## ")) in = test::starts_with(line, "## " + title);
    else if (in && test::starts_with(line, "| " + label + " ")) return line;
  }
  return "";
}

// Cells of a Markdown row, trimmed.
std::vector<std::string> cells(const std::string& row) {
  std::vector<std::string> out;
  std::string cur;
  for (size_t i = 1; i < row.size(); ++i) {
    if (row[i] == '|') {
      size_t b = cur.find_first_not_of(' '), e = cur.find_last_not_of(' ');
      out.push_back(b == std::string::npos ? "" : cur.substr(b, e - b + 1));
      cur.clear();
    } else {
      cur += row[i];
    }
  }
  return out;
}

// The user-error contract: exit code 1 and one line "causaldrive: error: ...". Returns it.
std::string expect_one_line_error(const CommandResult& r, const std::string& what) {
  EXPECT_TRUE(r.exited && !r.timed_out) << what << ": " << r.describe();
  EXPECT_EQ(r.exit_code, 1) << what << ": " << r.describe();
  std::vector<std::string> lines = test::split_lines(r.err);
  EXPECT_EQ(lines.size(), 1u) << what << ": stderr should be one line:\n" << r.err;
  if (lines.empty()) return "";
  EXPECT_TRUE(test::starts_with(lines.front(), "causaldrive: error:")) << lines.front();
  EXPECT_EQ(r.out, "") << what << ": nothing on stdout on an error";
  return lines.front();
}

TEST(ReportStats, MeanAndSampleStd) {
  CellStats s = mean_std({0.1, 0.2, 0.6});
  EXPECT_EQ(s.n, 3);
  EXPECT_NEAR(s.mean, 0.3, 1e-15);
  ASSERT_TRUE(s.std.has_value());
  EXPECT_NEAR(*s.std, std::sqrt(0.07), 1e-15);  // sqrt((0.04 + 0.01 + 0.09) / (3 - 1))
  CellStats one = mean_std({0.25});
  EXPECT_EQ(one.n, 1);
  EXPECT_EQ(one.mean, 0.25);
  EXPECT_FALSE(one.std.has_value()) << "no sample std from one seed";
  EXPECT_EQ(mean_std({}).n, 0);
}

TEST(ReportCli, SeedsGiveMeanAndSampleStdInCsvAndTable) {
  TempDir dir("cdtest-report");
  put(dir / "runs/bc-s0", results("bc", "town-a-regular",
                                  {{"error_rate", 0.10}, {"stall_rate", 0.5}}, "BC"));
  put(dir / "runs/bc-s1", results("bc", "town-a-regular",
                                  {{"error_rate", 0.20}, {"stall_rate", 0.25}}, "BC"));
  put(dir / "runs/bc-s2", results("bc", "town-a-dense", {{"error_rate", 0.1}}, "BC"));
  put(dir / "runs/bc-s3", results("bc", "town-a-dense", {{"error_rate", 0.2}}, "BC"));
  put(dir / "runs/bc-s4", results("bc", "town-a-dense", {{"error_rate", 0.6}}, "BC"));
  const std::string csv = dir / "out/report.csv";
  CommandResult r = test::run_cli({"report", dir / "runs", "--csv", csv});
  ASSERT_EQ(r.exit_code, 0) << r.describe();
  ASSERT_TRUE(fs::exists(csv)) << r.describe();
  std::vector<std::string> lines = report_lines(test::read_text(csv));
  ASSERT_FALSE(lines.empty());
  EXPECT_EQ(lines[0], "label,suite,metric,mean,std,n");
  auto has_line = [&](const std::string& want) {
    return std::find(lines.begin(), lines.end(), want) != lines.end();
  };
  // (0.10 + 0.20) / 2 = 0.15; sqrt(2 * 0.05^2 / (2 - 1)) = 0.05 * sqrt(2) = 0.0707106781187.
  EXPECT_TRUE(has_line("BC,town-a-regular,error_rate,0.15,0.0707106781187,2"))
      << test::read_text(csv);
  // 0.375 +- sqrt(2 * 0.125^2) = 0.176776695297 (0.125 * sqrt(2)).
  EXPECT_TRUE(has_line("BC,town-a-regular,stall_rate,0.375,0.176776695297,2"))
      << test::read_text(csv);
  // (0.1 + 0.2 + 0.6) / 3 = 0.3; sqrt((0.04 + 0.01 + 0.09) / 2) = sqrt(0.07) = 0.264575131106.
  EXPECT_TRUE(has_line("BC,town-a-dense,error_rate,0.3,0.264575131106,3")) << test::read_text(csv);
  // Equal values: std 0.
  EXPECT_TRUE(has_line("BC,town-a-dense,collision_rate,0.04,0,3")) << test::read_text(csv);
  // Each metric once though collision_rate is in three sets (error, outcomes, failure) and
  // success and inertia in two: 19 metrics x 2 suites + header (green_light_rate, the
  // collision kinds and the taxonomy's classes without a value in these files: rows with
  // n = 0).
  EXPECT_EQ(lines.size(), 1u + 2 * 19) << test::read_text(csv);
  EXPECT_TRUE(has_line("BC,town-a-dense,green_light_rate,,,0")) << test::read_text(csv);
  EXPECT_TRUE(has_line("BC,town-a-dense,paper_error_rate,,,0")) << test::read_text(csv);
  EXPECT_EQ(test::list_dir(dir / "out"), std::vector<std::string>{"report.csv"})
      << "no temporary file left beside the CSV";

  // The table shows the same in %, one decimal.
  // Error, inertia, collision, the paper's error and pedestrian collisions per suite.
  std::vector<std::string> row = cells(table_row(r.out, "Error rates", "BC"));
  ASSERT_EQ(row.size(), 1u + 2 * 5) << r.out;
  // Suites sorted: town-a-dense first.
  EXPECT_EQ(row[1], "30.0 \u00b1 26.5") << r.out;
  EXPECT_EQ(row[6], "15.0 \u00b1 7.1") << r.out;
  std::vector<std::string> stop = cells(table_row(r.out, "Stop-and-go", "BC"));
  ASSERT_EQ(stop.size(), 7u) << r.out;
  EXPECT_EQ(stop[4], "37.5 \u00b1 17.7") << r.out;
  EXPECT_EQ(stop[5], "1.3 \u00b1 0.0") << r.out;
}

TEST(ReportCli, MissingCellRowOrderAndColumnOrder) {
  TempDir dir("cdtest-report");
  // Paths sort a, b, c: labels first appear as "zeta", "alpha"; suites sort as s1, s2.
  put(dir / "runs/a", results("zeta-agent", "s2", {}, "zeta"));
  put(dir / "runs/b", results("alpha", "s1", {{"success_rate", 0.5}}));  // no label: agent
  put(dir / "runs/c", results("zeta-agent", "s1", {{"success_rate", 0.25}}, "zeta"));
  const std::string md = dir / "report.md", csv = dir / "report.csv";
  CommandResult r = test::run_cli(
      {"report", dir / "runs", "--metrics", "outcomes", "--markdown", md, "--csv", csv});
  ASSERT_EQ(r.exit_code, 0) << r.describe();
  EXPECT_EQ(test::read_text(md), r.out) << "--markdown writes what is printed";

  std::vector<std::string> lines = test::split_lines(r.out);
  ASSERT_GE(lines.size(), 6u) << r.out;
  EXPECT_TRUE(test::starts_with(lines[0], "## Outcomes")) << r.out;
  EXPECT_FALSE(has(r.out, "## Error")) << "--metrics outcomes prints one table\n" << r.out;
  std::vector<std::string> header = cells(lines[2]);
  // Nine columns per suite: success, collision, off-road, the five timeout classes, copycat.
  ASSERT_EQ(header.size(), 19u) << r.out;
  EXPECT_EQ(header[0], "label");
  EXPECT_EQ(header[1], "s1 success %");
  EXPECT_EQ(header[4], "s1 stuck %");
  EXPECT_EQ(header[9], "s1 copycat %");
  EXPECT_EQ(header[10], "s2 success %");
  EXPECT_TRUE(test::starts_with(lines[4], "| zeta ")) << r.out;
  EXPECT_TRUE(test::starts_with(lines[5], "| alpha ")) << r.out;

  std::vector<std::string> alpha = cells(lines[5]);
  ASSERT_EQ(alpha.size(), 19u);
  EXPECT_EQ(alpha[1], "50.0") << "one seed: the mean alone";
  EXPECT_EQ(alpha[4], "n/a") << "a run from before the taxonomy has no classes";
  EXPECT_EQ(alpha[10], kDash) << "alpha has no run on s2";
  EXPECT_EQ(alpha[11], kDash);
  EXPECT_EQ(alpha[18], kDash);
  std::vector<std::string> zeta = cells(lines[4]);
  EXPECT_EQ(zeta[1], "25.0");
  EXPECT_EQ(zeta[10], "90.0");

  std::string csv_text = test::read_text(csv);
  EXPECT_FALSE(has(csv_text, "alpha,s2,")) << "no rows for a missing cell\n" << csv_text;
  EXPECT_TRUE(has(csv_text, "alpha,s1,success_rate,0.5,,1\n")) << csv_text;
  EXPECT_LT(csv_text.find("zeta,"), csv_text.find("alpha,")) << csv_text;
}

TEST(ReportLibrary, NestedFoldersNullDelaysAndQuoting) {
  TempDir dir("cdtest-report");
  put(dir / "root/x/y/seed0", results("bc", "town-a-stopgo", {{"start_delay_median_s", 2.0}},
                                      "bc, target speed"));
  put(dir / "root/x/seed1", results("bc", "town-a-stopgo", {{"start_delay_median_s", 4.0}},
                                    "bc, target speed"));
  put(dir / "root", results("cim", "town-a-stopgo",
                            {{"start_delay_median_s", nullptr}, {"start_delay_p90_s", nullptr},
                             {"stall_rate", nullptr}}));
  test::write_text(dir / "root/x/notes.json", "not json, and not a results.json");
  // The same folder twice (directly and through its parent) counts once; paths sorted.
  std::vector<std::string> files = find_result_files({dir / "root", dir / "root/x"});
  EXPECT_EQ(files, (std::vector<std::string>{dir / "root/results.json",
                                             dir / "root/x/seed1/results.json",
                                             dir / "root/x/y/seed0/results.json"}));
  std::vector<RunResult> runs;
  for (const auto& f : files) runs.push_back(load_result(f));
  ReportTable table = build_report(runs);
  EXPECT_EQ(table.labels, (std::vector<std::string>{"cim", "bc, target speed"}));
  std::vector<MetricSet> sets = parse_metric_sets("stopgo");
  std::string csv = render_csv(table, sets);
  EXPECT_TRUE(has(csv, "\"bc, target speed\",town-a-stopgo,start_delay_median_s,3,"
                       "1.41421356237,2\n"))
      << csv;
  EXPECT_TRUE(has(csv, "cim,town-a-stopgo,start_delay_median_s,,,0\n")) << csv;
  std::string md = render_markdown(table, sets);
  std::vector<std::string> cim = cells(table_row(md, "Stop-and-go", "cim"));
  ASSERT_EQ(cim.size(), 4u) << md;
  EXPECT_EQ(cim[1], "n/a") << "a run without events has no delay";
  EXPECT_EQ(cim[2], "n/a");
  EXPECT_LT(md.find("| cim "), md.find("| bc, target speed ")) << md;
}

TEST(ReportCli, MetricsAllIsDefault) {
  TempDir dir("cdtest-report");
  put(dir / "run", results("bc", "s1"));
  CommandResult r = test::run_cli({"report", dir / "run"});
  ASSERT_EQ(r.exit_code, 0) << r.describe();
  size_t e = r.out.find("## Error rates"), o = r.out.find("## Outcomes"),
         s = r.out.find("## Stop-and-go");
  ASSERT_NE(e, std::string::npos) << r.out;
  ASSERT_NE(o, std::string::npos) << r.out;
  ASSERT_NE(s, std::string::npos) << r.out;
  EXPECT_LT(e, o);
  EXPECT_LT(o, s);
  std::vector<RunResult> runs = {load_result(dir / "run/results.json")};
  std::string two = render_markdown(build_report(runs), parse_metric_sets("stopgo,error,stopgo"));
  EXPECT_LT(two.find("## Stop-and-go"), two.find("## Error")) << two;
  EXPECT_EQ(two.find("## Stop-and-go"), two.rfind("## Stop-and-go")) << "each set once\n" << two;
  EXPECT_FALSE(has(two, "## Outcomes")) << two;
}

// A free-steering run (a lateral error in its summary) brings the lateral-control table into the
// default report, off-road beside the error; route-mode runs alone do not.
TEST(ReportCli, FreeSteeringRunsAddTheLateralTableByDefault) {
  TempDir dir("cdtest-report");
  put(dir / "route", results("expert", "town-a-regular",
                             {{"offroad_rate", 0.0}, {"mean_lateral_error_m", nullptr}}, "route"));
  CommandResult r = test::run_cli({"report", dir / "route"});
  ASSERT_EQ(r.exit_code, 0) << r.describe();
  EXPECT_FALSE(has(r.out, "## Lateral control")) << r.out;
  put(dir / "free", results("dim", "town-a-regular",
                            {{"success_rate", 0.2}, {"collision_rate", 0.3},
                             {"timeout_rate", 0.0}, {"inertia_rate", 0.0}, {"error_rate", 0.3},
                             {"offroad_rate", 0.5}, {"mean_lateral_error_m", 0.42},
                             {"wrong_way_per_km", 1.25}, {"lane_invasions_per_km", 3.0},
                             {"lane_changes_per_km", 0.0}},
                            "free"));
  r = test::run_cli({"report", dir / "route", dir / "free"});
  ASSERT_EQ(r.exit_code, 0) << r.describe();
  ASSERT_TRUE(has(r.out, "## Lateral control")) << r.out;
  const std::string lateral = r.out.substr(r.out.find("## Lateral control"));
  EXPECT_TRUE(has(lateral, "town-a-regular off-road %")) << lateral;
  // free: off-road 50.0, error 30.0, wrong way 1.25 / km, lateral error 0.42 m.
  const std::string free_row = lateral.substr(lateral.find("| free"));
  EXPECT_TRUE(has(free_row, "50.0")) << free_row;
  EXPECT_TRUE(has(free_row, "1.25")) << free_row;
  EXPECT_TRUE(has(free_row, "0.42")) << free_row;
  EXPECT_TRUE(has(lateral.substr(lateral.find("| route")), "n/a")) << "route: no lateral error";
  // An explicit --metrics is kept as given.
  r = test::run_cli({"report", dir / "free", "--metrics", "error"});
  ASSERT_EQ(r.exit_code, 0) << r.describe();
  EXPECT_FALSE(has(r.out, "## Lateral control")) << r.out;
  std::vector<RunResult> runs = {load_result(dir / "free/results.json")};
  EXPECT_TRUE(steers_freely(runs[0]));
  EXPECT_EQ(default_metric_sets(runs).back().name, "lateral");
}

TEST(ReportErrors, MissingFolder) {
  TempDir dir("cdtest-report");
  std::string line = expect_one_line_error(test::run_cli({"report", dir / "nope"}), "missing");
  EXPECT_TRUE(has(line, dir / "nope")) << line;
  EXPECT_TRUE(has(line, "does not exist")) << line;
}

TEST(ReportErrors, FolderWithoutResults) {
  TempDir dir("cdtest-report");
  put(dir / "good", results("bc", "s1"));
  fs::create_directories(dir / "empty/sub");
  std::string csv = dir / "r.csv";
  std::string line = expect_one_line_error(
      test::run_cli({"report", dir / "good", dir / "empty", "--csv", csv}), "empty folder");
  EXPECT_TRUE(has(line, dir / "empty")) << line;
  EXPECT_TRUE(has(line, "no results.json")) << line;
  EXPECT_FALSE(fs::exists(csv)) << "nothing written on an error";
}

TEST(ReportErrors, InvalidJson) {
  TempDir dir("cdtest-report");
  fs::create_directories(dir / "run");
  test::write_text(dir / "run/results.json", "{\"agent\": \"bc\",\n \"suite\": }\n");
  std::string line = expect_one_line_error(test::run_cli({"report", dir / "run"}), "bad JSON");
  EXPECT_TRUE(has(line, dir / "run/results.json")) << line;
  EXPECT_TRUE(has(line, "not valid JSON")) << line;
  EXPECT_TRUE(has(line, "line 2")) << line;
}

TEST(ReportErrors, MissingKeys) {
  TempDir dir("cdtest-report");
  put(dir / "ok", results("bc", "s1"));
  for (const std::string key : {"agent", "suite", "summary"}) {
    nlohmann::json j = results("bc", "s2");
    j.erase(key);
    put(dir / ("no-" + key), j);
    const std::string file = dir / ("no-" + key + "/results.json");
    try {
      load_result(file);
      ADD_FAILURE() << "no error without " << key;
    } catch (const DataError& e) {
      EXPECT_TRUE(has(e.what(), file)) << e.what();
      EXPECT_TRUE(has(e.what(), "'" + key + "'")) << e.what();
    }
  }
  // Through the CLI: one line naming the first broken file (sorted: no-agent) and the key.
  std::string line = expect_one_line_error(test::run_cli({"report", dir.path()}), "no agent");
  EXPECT_TRUE(has(line, dir / "no-agent/results.json")) << line;
  EXPECT_TRUE(has(line, "'agent'")) << line;
}

TEST(ReportErrors, BadSummaryValues) {
  TempDir dir("cdtest-report");
  put(dir / "run", results("bc", "s1", {{"inertia_rate", 12.5}}));
  std::string line = expect_one_line_error(test::run_cli({"report", dir / "run"}), "rate > 1");
  EXPECT_TRUE(has(line, dir / "run/results.json")) << line;
  EXPECT_TRUE(has(line, "summary.inertia_rate")) << line;
  put(dir / "run", results("bc", "s1", {{"start_delay_p90_s", "slow"}}));
  EXPECT_THROW(
      {
        try {
          load_result(dir / "run/results.json");
        } catch (const DataError& e) {
          EXPECT_TRUE(has(e.what(), "summary.start_delay_p90_s")) << e.what();
          throw;
        }
      },
      DataError);
}

TEST(ReportErrors, UnknownMetricsAndNoRunDir) {
  TempDir dir("cdtest-report");
  put(dir / "run", results("bc", "s1"));
  std::string line = expect_one_line_error(
      test::run_cli({"report", dir / "run", "--metrics", "errors"}), "--metrics errors");
  EXPECT_TRUE(has(line, "--metrics")) << line;
  EXPECT_TRUE(has(line, "'errors'")) << line;
  EXPECT_TRUE(has(line, "outcomes")) << "lists the choices: " << line;
  line = expect_one_line_error(test::run_cli({"report"}), "no RUN_DIR");
  EXPECT_TRUE(has(line, "RUN_DIR")) << line;
}

// A run of the failure-mode tables: town and sensor as eval writes them.
nlohmann::json run(const std::string& label, const std::string& suite, const std::string& town,
                   const std::string& sensor, double success, double collision, double timeout) {
  nlohmann::json j = results("agent-" + label, suite,
                             {{"success_rate", success}, {"collision_rate", collision},
                              {"timeout_rate", timeout / 2}, {"inertia_rate", timeout / 2},
                              {"time_limit_rate", timeout}},
                             label);
  j["town"] = town;
  j["sensor"] = sensor;
  return j;
}

TEST(ReportFailureModes, OneTablePerConditionWithTrafficColumns) {
  TempDir dir("cdtest-report");
  put(dir / "runs/a/bc-s0", run("bc", "town-a-regular", "town-a", "clean", 0.6, 0.3, 0.1));
  put(dir / "runs/a/bc-s1", run("bc", "town-a-regular", "town-a", "clean", 0.8, 0.1, 0.1));
  put(dir / "runs/a/bc-s2", run("bc", "town-a-dense", "town-a", "clean", 0.4, 0.5, 0.1));
  put(dir / "runs/a/bc-stopgo", run("bc", "town-a-stopgo", "town-a", "clean", 0.9, 0.0, 0.1));
  put(dir / "runs/a/res-s0", run("res", "town-a-regular", "town-a", "clean", 0.9, 0.05, 0.05));
  put(dir / "runs/s/bc-s0", run("bc", "town-a-regular", "town-a", "shifted", 0.2, 0.5, 0.3));
  put(dir / "runs/s/bc-s1", run("bc", "town-a-regular", "town-a", "shifted", 0.4, 0.5, 0.1));
  put(dir / "runs/t/bc-s0", run("bc", "town-b-dense", "town-b", "clean", 0.1, 0.7, 0.2));
  put(dir / "runs/t/res-s0", run("res", "town-b-regular", "town-b", "clean", 0.5, 0.25, 0.25));
  put(dir / "runs/u/bc-c", run("bc", "town-c-regular", "town-c", "clean", 0.0, 1.0, 0.0));
  CommandResult r = test::run_cli({"report", dir / "runs", "--metrics", "failure"});
  ASSERT_EQ(r.exit_code, 0) << r.describe();

  // Seed 001's order: training conditions (table 7), new weather (8), new town (9).
  const size_t t = r.out.find("## Failure modes, training town (town-a, clean sensor"),
               s = r.out.find("## Failure modes, new sensor (town-a, shifted sensor"),
               n = r.out.find("## Failure modes, new town (town-b, clean sensor");
  ASSERT_NE(t, std::string::npos) << r.out;
  ASSERT_NE(s, std::string::npos) << r.out;
  ASSERT_NE(n, std::string::npos) << r.out;
  EXPECT_LT(t, s);
  EXPECT_LT(s, n);
  EXPECT_FALSE(has(r.out, "town-c")) << "the adaptation town is in no condition\n" << r.out;
  EXPECT_FALSE(has(r.out, "## Error")) << r.out;

  // Training town: traffic columns without the town, NoCrash order, then the others.
  std::vector<std::string> lines = test::split_lines(r.out.substr(t));
  ASSERT_GE(lines.size(), 6u) << r.out;
  std::vector<std::string> header = cells(lines[2]);
  // Seed 001's #TIMEOUT is every episode out of time (time_limit_rate); inertia beside it.
  ASSERT_EQ(header.size(), 1u + 3 * 4) << r.out;
  EXPECT_EQ(header[1], "regular success %");
  EXPECT_EQ(header[2], "regular collision %");
  EXPECT_EQ(header[3], "regular timeout %");
  EXPECT_EQ(header[4], "regular inertia %");
  EXPECT_EQ(header[5], "dense success %");
  EXPECT_EQ(header[9], "stopgo success %");
  std::vector<std::string> bc = cells(table_row(r.out, "Failure modes, training town", "bc"));
  ASSERT_EQ(bc.size(), 13u) << r.out;
  // Two seeds on regular: 70 +- 14.1 (sqrt(2) * 10), 20 +- 14.1, 10 +- 0; the shifted runs
  // are not seeds of it.
  EXPECT_EQ(bc[1], "70.0 \u00b1 14.1") << r.out;
  EXPECT_EQ(bc[2], "20.0 \u00b1 14.1") << r.out;
  EXPECT_EQ(bc[3], "10.0 \u00b1 0.0") << r.out;
  EXPECT_EQ(bc[4], "5.0 \u00b1 0.0") << r.out;
  EXPECT_EQ(bc[5], "40.0") << r.out;
  EXPECT_EQ(bc[9], "90.0") << r.out;
  std::vector<std::string> res = cells(table_row(r.out, "Failure modes, training town", "res"));
  ASSERT_EQ(res.size(), 13u) << r.out;
  EXPECT_EQ(res[1], "90.0");
  EXPECT_EQ(res[5], kDash) << "res has no dense run";

  // New sensor: the shifted runs only, bc alone.
  std::vector<std::string> sbc = cells(table_row(r.out, "Failure modes, new sensor", "bc"));
  ASSERT_EQ(sbc.size(), 5u) << r.out;
  EXPECT_EQ(sbc[1], "30.0 \u00b1 14.1");
  EXPECT_EQ(sbc[2], "50.0 \u00b1 0.0");
  EXPECT_EQ(sbc[3], "20.0 \u00b1 14.1");
  EXPECT_EQ(table_row(r.out, "Failure modes, new sensor", "res"), "") << r.out;

  // New town: town-b, regular before dense.
  std::vector<std::string> header_b = cells(test::split_lines(r.out.substr(n))[2]);
  ASSERT_EQ(header_b.size(), 9u) << r.out;
  EXPECT_EQ(header_b[1], "regular success %");
  EXPECT_EQ(header_b[5], "dense success %");
  std::vector<std::string> tbc = cells(table_row(r.out, "Failure modes, new town", "bc"));
  ASSERT_EQ(tbc.size(), 9u) << r.out;
  EXPECT_EQ(tbc[1], kDash);
  EXPECT_EQ(tbc[6], "70.0");
  std::vector<std::string> tres = cells(table_row(r.out, "Failure modes, new town", "res"));
  EXPECT_EQ(tres[3], "25.0");
}

TEST(ReportFailureModes, ShiftedRunsHaveTheirOwnColumnsAndTheLightsTable) {
  TempDir dir("cdtest-report");
  put(dir / "runs/c0", run("bc", "town-a-regular", "town-a", "clean", 0.8, 0.1, 0.1));
  put(dir / "runs/s0", run("bc", "town-a-regular", "town-a", "shifted", 0.2, 0.6, 0.2));
  nlohmann::json lit = run("cim", "town-a-regular", "town-a", "clean", 1.0, 0.0, 0.0);
  lit["summary"]["green_light_rate"] = 0.75;
  put(dir / "runs/l0", lit);
  lit["summary"]["green_light_rate"] = 0.25;
  put(dir / "runs/l1", lit);
  nlohmann::json none = run("cs", "town-a-regular", "town-a", "clean", 1.0, 0.0, 0.0);
  none["summary"]["green_light_rate"] = nullptr;  // no light passed
  put(dir / "runs/n0", none);
  const std::string csv = dir / "report.csv";
  CommandResult r = test::run_cli({"report", dir / "runs", "--csv", csv});
  ASSERT_EQ(r.exit_code, 0) << r.describe();
  std::vector<std::string> bc = cells(table_row(r.out, "Outcomes", "bc"));
  ASSERT_EQ(bc.size(), 19u) << "clean and shifted are two column groups\n" << r.out;
  EXPECT_EQ(bc[1], "80.0") << r.out;
  EXPECT_EQ(bc[10], "20.0") << r.out;
  EXPECT_TRUE(has(r.out, "town-a-regular (shifted sensor) success %")) << r.out;
  const std::string text = test::read_text(csv);
  EXPECT_TRUE(has(text, "bc,town-a-regular (shifted sensor),success_rate,0.2,,1\n")) << text;
  EXPECT_TRUE(has(text, "bc,town-a-regular,success_rate,0.8,,1\n")) << text;

  // All sets by default: the lights table (green-light rate mean +- sd over seeds, n/a
  // without passages) and the failure modes after the stop-and-go table.
  const size_t g = r.out.find("## Traffic lights"), f = r.out.find("## Failure modes, training");
  ASSERT_NE(g, std::string::npos) << r.out;
  ASSERT_NE(f, std::string::npos) << r.out;
  EXPECT_LT(r.out.find("## Stop-and-go"), g);
  EXPECT_LT(g, f);
  std::vector<std::string> cim = cells(table_row(r.out, "Traffic lights", "cim"));
  ASSERT_GE(cim.size(), 3u) << r.out;
  EXPECT_EQ(cim[1], "50.0 \u00b1 35.4") << r.out;  // sqrt(2) * 25
  EXPECT_EQ(cim[2], "0.10 \u00b1 0.00") << "red lights per km, two decimals";
  EXPECT_EQ(cells(table_row(r.out, "Traffic lights", "cs"))[1], "n/a") << r.out;
  EXPECT_TRUE(has(text, "cim,town-a-regular,green_light_rate,0.5,0.353553390593,2\n")) << text;
}

// The camera's held-out weather (seed 001's table 8 for the camera) is a condition of its own:
// read from `weather`, or, in files written before eval recorded it, off the episodes' weathers.
TEST(ReportFailureModes, HeldOutWeatherRunsAreTheNewSensorCondition) {
  TempDir dir("cdtest-report");
  auto camera_run = [](double success, const std::vector<std::string>& weathers,
                       const std::string& label = "bc") {
    nlohmann::json j = run(label, "town-a-regular", "town-a", "clean", success, 1 - success, 0.0);
    j["episodes"] = nlohmann::json::array();
    for (size_t i = 0; i < weathers.size(); ++i)
      j["episodes"].push_back({{"task", i}, {"outcome", "success"}, {"weather", weathers[i]}});
    return j;
  };
  // Training pool, recorded and derived; held-out, recorded and derived (two seeds each).
  nlohmann::json a = camera_run(0.8, {"clear-noon", "wet-noon"});
  a["weather"] = "train";
  put(dir / "runs/t0", a);
  put(dir / "runs/t1", camera_run(0.6, {"hard-rain-noon", "clear-sunset"}));
  nlohmann::json h = camera_run(0.3, {"clear-noon"});  // the key wins over the episodes
  h["weather"] = "held-out";
  put(dir / "runs/h0", h);
  put(dir / "runs/h1", camera_run(0.1, {"soft-rain-sunset", "after-rain-dusk"}));
  // One set named: a column of its own; a training set is no new sensor, a held-out one is.
  nlohmann::json noon = camera_run(0.9, {"clear-noon"}, "noon");
  noon["weather"] = "clear-noon";
  put(dir / "runs/n0", noon);
  nlohmann::json dusk = camera_run(0.4, {"after-rain-dusk"}, "dusk");
  dusk["weather"] = "after-rain-dusk";
  put(dir / "runs/d0", dusk);
  CommandResult r = test::run_cli({"report", dir / "runs", "--metrics", "outcomes,failure",
                                   "--spread", "sd"});
  ASSERT_EQ(r.exit_code, 0) << r.describe();
  EXPECT_TRUE(has(r.out, "| town-a-regular (held-out weather) success %")) << r.out;
  std::vector<std::string> bc = cells(table_row(r.out, "Outcomes", "bc"));
  ASSERT_GE(bc.size(), 2u) << r.out;
  EXPECT_EQ(bc[1], "70.0 \u00b1 14.1") << "the two training-pool runs are its seeds\n" << r.out;
  std::vector<std::string> t = cells(table_row(r.out, "Failure modes, training town", "bc"));
  ASSERT_GE(t.size(), 2u) << r.out;
  EXPECT_EQ(t[1], "70.0 \u00b1 14.1") << r.out;
  std::vector<std::string> s = cells(table_row(r.out, "Failure modes, new sensor", "bc"));
  ASSERT_GE(s.size(), 2u) << r.out;
  EXPECT_EQ(s[1], "20.0 \u00b1 14.1") << "the held-out runs are table 8's\n" << r.out;
  EXPECT_TRUE(has(r.out, "new sensor (town-a, shifted sensor or held-out weather")) << r.out;
  EXPECT_TRUE(has(r.out, "| town-a-regular (clear-noon weather) success %")) << r.out;
  EXPECT_EQ(cells(table_row(r.out, "Failure modes, training town", "noon")).at(1), "90.0")
      << r.out;
  EXPECT_EQ(table_row(r.out, "Failure modes, new sensor", "noon"), "") << r.out;
  EXPECT_EQ(cells(table_row(r.out, "Failure modes, new sensor", "dusk")).at(1), "40.0") << r.out;
  EXPECT_EQ(table_row(r.out, "Failure modes, training town", "dusk"), "") << r.out;

  // A weather that is no camera set is named.
  put(dir / "bad", camera_run(0.5, {"clear-noon", "monsoon"}));
  std::string line = expect_one_line_error(test::run_cli({"report", dir / "bad"}), "monsoon");
  EXPECT_TRUE(has(line, "'monsoon'")) << line;
}

TEST(ReportFailureModes, NoRunInAnyConditionSaysSo) {
  TempDir dir("cdtest-report");
  put(dir / "run", run("bc", "town-c-regular", "town-c", "clean", 0.5, 0.5, 0.0));
  CommandResult r = test::run_cli({"report", dir / "run", "--metrics", "failure"});
  ASSERT_EQ(r.exit_code, 0) << r.describe();
  EXPECT_TRUE(test::starts_with(r.out, "## Failure modes\n\nno run in any condition: training "
                                       "town (town-a, clean sensor)"))
      << r.out;
  // A malformed sensor is named.
  nlohmann::json bad = run("bc", "town-a-regular", "town-a", "clean", 0.5, 0.5, 0.0);
  bad["sensor"] = 3;
  put(dir / "bad", bad);
  std::string line = expect_one_line_error(test::run_cli({"report", dir / "bad"}), "sensor 3");
  EXPECT_TRUE(has(line, "'sensor'")) << line;
}

}  // namespace
}  // namespace cd

namespace cd {
namespace {

// A driving results.json whose episodes are listed: `outcomes[t][k]` is trial k of task t.
nlohmann::json with_episodes(const std::string& label, const std::string& suite,
                             const std::vector<std::vector<std::string>>& outcomes) {
  nlohmann::json eps = nlohmann::json::array();
  long n = 0, success = 0;
  for (size_t t = 0; t < outcomes.size(); ++t)
    for (size_t k = 0; k < outcomes[t].size(); ++k) {
      eps.push_back({{"task", t}, {"trial", k}, {"outcome", outcomes[t][k]}});
      ++n;
      success += outcomes[t][k] == "success";
    }
  nlohmann::json j = results(label, suite, {{"episodes", n},
                                            {"success_rate", double(success) / n}});
  j["label"] = label;
  j["episodes"] = eps;
  return j;
}

TEST(ReportIntervals, RatesGetTheirIntervalComparisonsAndPower) {
  TempDir dir("cdtest-report");
  // Two labels x 3 seeds x 2 suites, 4 tasks x 2 trials each; A succeeds more often.
  const std::vector<std::vector<std::vector<std::string>>> a_seeds = {
      {{"success", "success"}, {"success", "collision"}, {"success", "success"}, {"stuck", "success"}},
      {{"success", "success"}, {"success", "success"}, {"collision", "success"}, {"success", "success"}},
      {{"success", "blocked"}, {"success", "success"}, {"success", "success"}, {"success", "success"}}};
  const std::vector<std::vector<std::vector<std::string>>> b_seeds = {
      {{"collision", "success"}, {"stuck", "collision"}, {"success", "stuck"}, {"stuck", "success"}},
      {{"success", "collision"}, {"collision", "stuck"}, {"collision", "success"}, {"stuck", "stuck"}},
      {{"stuck", "blocked"}, {"success", "collision"}, {"collision", "stuck"}, {"success", "stuck"}}};
  for (const char* suite : {"town-a-regular", "town-a-dense"})
    for (int s = 0; s < 3; ++s) {
      put(dir / ("runs/" + std::string(suite) + "/a/seed" + std::to_string(s)),
          with_episodes("A", suite, a_seeds[s]));
      put(dir / ("runs/" + std::string(suite) + "/b/seed" + std::to_string(s)),
          with_episodes("B", suite, b_seeds[s]));
    }
  // The oracle: the library's interval of the same seeds x tasks (its coverage is tested in
  // test_intervals.cpp), per-task shares by hand.
  // Per seed and task, the share of its two trials that ended in `outcome`.
  auto shares_of = [](const std::vector<std::vector<std::vector<std::string>>>& all,
                      const std::string& outcome) {
    SeedRuns runs;
    for (const auto& seed : all) {
      SeedOutcomes o;
      o.trials = 2;
      for (const auto& task : seed)
        o.per_task.push_back((task[0] == outcome) * 0.5 + (task[1] == outcome) * 0.5);
      runs.push_back(o);
    }
    return runs;
  };
  auto seeds_of = [&](const std::vector<std::vector<std::vector<std::string>>>& all) {
    return shares_of(all, "success");
  };
  const Interval ia = rate_interval(seeds_of(a_seeds));
  auto fmt1 = [](double v) {
    char b[32];
    std::snprintf(b, sizeof b, "%.1f", 100 * v);
    return std::string(b);
  };
  CommandResult r = test::run_cli({"report", dir / "runs", "--metrics", "outcomes"});
  ASSERT_EQ(r.exit_code, 0) << r.describe();
  const std::string want = fmt1(ia.mean) + " [" + fmt1(ia.lo) + ", " + fmt1(ia.hi) + "]";
  EXPECT_TRUE(has(r.out, want)) << want << "\n" << r.out;
  CommandResult sd = test::run_cli({"report", dir / "runs", "--metrics", "outcomes", "--spread", "sd"});
  ASSERT_EQ(sd.exit_code, 0) << sd.describe();
  EXPECT_FALSE(has(sd.out, want)) << sd.out;
  EXPECT_TRUE(has(sd.out, " \u00b1 ")) << sd.out;

  CommandResult c = test::run_cli(
      {"report", dir / "runs", "--metrics", "outcomes", "--compare", "A", "B", "--power", "--json"});
  ASSERT_EQ(c.exit_code, 0) << c.describe();
  const nlohmann::json j = nlohmann::json::parse(c.out);
  const Comparison want_c = compare(seeds_of(a_seeds), seeds_of(b_seeds));
  ASSERT_EQ(j["compare"]["conditions"].size(), 2u) << c.out;
  const nlohmann::json& one = j["compare"]["conditions"][0];
  EXPECT_DOUBLE_EQ(one["difference"].get<double>(), want_c.difference);
  EXPECT_DOUBLE_EQ(one["p_improvement"].get<double>(), want_c.p_improvement);
  EXPECT_EQ(one["verdict"], verdict_text(want_c.verdict));
  EXPECT_TRUE(j["compare"].contains("over_conditions")) << c.out;
  CommandResult md = test::run_cli({"report", dir / "runs", "--compare", "A", "B"});
  ASSERT_EQ(md.exit_code, 0) << md.describe();
  EXPECT_TRUE(has(md.out, "| A better |")) << md.out;  // three seeds a side: not interim
  EXPECT_FALSE(has(md.out, "interim")) << md.out;
  const PowerPlan want_p = power(variance_components(seeds_of(a_seeds)), 0.10);
  bool found = false;
  for (const auto& p : j["power"]["cells"])
    if (p["label"] == "A" && p["condition"] == "town-a-regular") {
      found = true;
      EXPECT_EQ(p["seeds_needed"].get<long>(), want_p.seeds_needed);
      EXPECT_DOUBLE_EQ(p["rate_half_width"].get<double>(), want_p.rate_half_width);
    }
  EXPECT_TRUE(found) << c.out;
  bool interval = false;
  for (const auto& cell : j["cells"])
    if (cell["label"] == "A" && cell["metric"] == "success_rate") {
      interval = true;
      EXPECT_DOUBLE_EQ(cell["lo"].get<double>(), ia.lo);
      EXPECT_DOUBLE_EQ(cell["hi"].get<double>(), ia.hi);
    }
  EXPECT_TRUE(interval) << c.out;

  // A failure rate: the lower one is better, so the library's "A higher" is "B better".
  auto collisions_of = [&](const std::vector<std::vector<std::vector<std::string>>>& all) {
    return shares_of(all, "collision");
  };
  CommandResult cc = test::run_cli({"report", dir / "runs", "--metrics", "outcomes", "--compare",
                                    "A", "B", "--compare-metric", "collision_rate", "--json"});
  ASSERT_EQ(cc.exit_code, 0) << cc.describe();
  const nlohmann::json jc = nlohmann::json::parse(cc.out)["compare"];
  const Comparison raw = compare(collisions_of(a_seeds), collisions_of(b_seeds));
  ASSERT_NE(raw.verdict, Verdict::not_resolved) << "the case should resolve";
  EXPECT_FALSE(jc["higher_is_better"].get<bool>());
  EXPECT_DOUBLE_EQ(jc["conditions"][0]["difference"].get<double>(), raw.difference);
  EXPECT_EQ(jc["conditions"][0]["verdict"],
            verdict_text(raw.verdict == Verdict::a_better ? Verdict::b_better : Verdict::a_better));
  EXPECT_TRUE(j["compare"]["higher_is_better"].get<bool>());

  std::string line = expect_one_line_error(
      test::run_cli({"report", dir / "runs", "--compare", "A", "C"}), "unknown label");
  EXPECT_TRUE(has(line, "no run is labelled 'C'")) << line;
  line = expect_one_line_error(test::run_cli({"report", dir / "runs", "--compare", "A", "B",
                                              "--compare-metric", "stall_rate"}),
                               "not a rate of episodes");
  EXPECT_TRUE(has(line, "is not a share of episodes")) << line;
}

// A label with one seed has no seed variance to measure: its power row says so (seed sd n/a,
// the seeds needed a lower bound) instead of planning as if the seeds agreed exactly, and a
// comparison with it marks its verdict interim.
TEST(ReportIntervals, OneSeedIsMarkedInPowerAndComparisons) {
  TempDir dir("cdtest-report");
  const std::vector<std::vector<std::string>> one = {
      {"success", "collision"}, {"stuck", "success"}, {"success", "success"}, {"collision", "stuck"}};
  const std::vector<std::vector<std::string>> other = {
      {"success", "success"}, {"success", "stuck"}, {"collision", "success"}, {"success", "success"}};
  put(dir / "runs/town-a-regular/a/seed0", with_episodes("A", "town-a-regular", one));
  put(dir / "runs/town-a-regular/b/seed0", with_episodes("B", "town-a-regular", one));
  put(dir / "runs/town-a-regular/b/seed1", with_episodes("B", "town-a-regular", other));
  CommandResult r = test::run_cli({"report", dir / "runs", "--metrics", "outcomes", "--power"});
  ASSERT_EQ(r.exit_code, 0) << r.describe();
  // A: 1 seed of 8 episodes (4 successes); by hand, the episode variance 0.5 * 0.5 * 8 / 7 and
  // seeds_for(8) = ceil(2 * 7.849 * (2/7) / 8 / 0.01) = ceil(56.07) = 57.
  std::string a_row, b_row;
  std::istringstream lines(r.out);
  for (std::string line; std::getline(lines, line);) {
    if (line.rfind("| A | town-a-regular |", 0) == 0) a_row = line;
    if (line.rfind("| B | town-a-regular |", 0) == 0) b_row = line;
  }
  EXPECT_TRUE(has(a_row, "| 1 | 8 | n/a | 53.5 |")) << a_row;
  EXPECT_TRUE(has(a_row, "| \u2265 57 | \u2265 15 |")) << a_row;
  EXPECT_FALSE(has(b_row, "n/a")) << b_row;
  EXPECT_FALSE(has(b_row, "\u2265")) << b_row;
  EXPECT_TRUE(has(r.out, "a row of one seed has no seed sd to measure")) << r.out;
  CommandResult j = test::run_cli({"report", dir / "runs", "--metrics", "outcomes", "--power", "--json"});
  ASSERT_EQ(j.exit_code, 0) << j.describe();
  for (const auto& cell : nlohmann::json::parse(j.out)["power"]["cells"])
    EXPECT_EQ(cell["seed_variance_known"].get<bool>(), cell["label"] == "B") << cell.dump();

  CommandResult c = test::run_cli({"report", dir / "runs", "--compare", "A", "B"});
  ASSERT_EQ(c.exit_code, 0) << c.describe();
  EXPECT_TRUE(has(c.out, "| not resolved (one seed: interim) |")) << c.out;
  EXPECT_TRUE(has(c.out, "counts the episodes' noise alone")) << c.out;
  CommandResult cj = test::run_cli({"report", dir / "runs", "--compare", "A", "B", "--json"});
  ASSERT_EQ(cj.exit_code, 0) << cj.describe();
  const nlohmann::json row = nlohmann::json::parse(cj.out)["compare"]["conditions"][0];
  EXPECT_TRUE(row["episode_only"].get<bool>()) << row.dump();
  EXPECT_EQ(row["verdict"], "not resolved") << row.dump();  // the JSON keeps the plain verdict
}

// MuJoCo-Image runs (results.json with `env`, per-episode returns): the IQM of the returns over
// seeds x episodes with its bootstrap interval, seeded.
TEST(ReportIntervals, MujocoReturnsGetTheirIqmAndASeededBootstrapInterval) {
  TempDir dir("cdtest-report-iqm");
  // 3 seeds x 4 episodes. Pooled and sorted: 1 2 3 | 4 5 6 7 8 9 | 10 11 100; trim_mean(., 0.25)
  // drops 3 at each end: (4 + 5 + 6 + 7 + 8 + 9) / 6 = 6.5 (the plain mean is 14.67).
  const std::vector<std::vector<double>> returns = {{1, 5, 9, 100}, {2, 6, 10, 4}, {3, 7, 11, 8}};
  for (int s = 0; s < 3; ++s) {
    nlohmann::json eps = nlohmann::json::array();
    double sum = 0;
    for (int i = 0; i < 4; ++i) {
      eps.push_back({{"index", i}, {"seed", i}, {"return", returns[s][i]}, {"length", 100}});
      sum += returns[s][i];
    }
    put(dir / ("runs/s" + std::to_string(s)),
        {{"agent", "bc-oh"}, {"env", "halfcheetah"}, {"episodes", eps},
         {"summary", {{"episodes", 4}, {"mean_return", sum / 4}, {"mean_length", 100}}}});
  }
  auto cell = [](const std::string& out) {
    const nlohmann::json doc = nlohmann::json::parse(out);
    for (const auto& c : doc["cells"])
      if (c["metric"] == "iqm_return") return c;
    return nlohmann::json();
  };
  CommandResult r = test::run_cli({"report", dir / "runs", "--json"});
  ASSERT_EQ(r.exit_code, 0) << r.describe();
  const nlohmann::json c = cell(r.out);
  ASSERT_FALSE(c.is_null()) << r.out;
  EXPECT_DOUBLE_EQ(c["mean"].get<double>(), 6.5);
  EXPECT_LE(c["lo"].get<double>(), 6.5);
  EXPECT_GE(c["hi"].get<double>(), 6.5);
  EXPECT_LT(c["lo"].get<double>(), c["hi"].get<double>());
  EXPECT_EQ(c["episodes"], 12);
  const IqmInterval want = iqm_interval(returns, 0, 10000);
  EXPECT_DOUBLE_EQ(c["lo"].get<double>(), want.lo);
  EXPECT_DOUBLE_EQ(c["hi"].get<double>(), want.hi);
  EXPECT_EQ(test::run_cli({"report", dir / "runs", "--json"}).out, r.out);  // same bytes
  const nlohmann::json other =
      cell(test::run_cli({"report", dir / "runs", "--json", "--bootstrap-seed", "7",
                          "--resamples", "500"}).out);
  const IqmInterval want7 = iqm_interval(returns, 7, 500);
  EXPECT_DOUBLE_EQ(other["lo"].get<double>(), want7.lo);
  EXPECT_DOUBLE_EQ(other["hi"].get<double>(), want7.hi);
  CommandResult md = test::run_cli({"report", dir / "runs"});
  ASSERT_EQ(md.exit_code, 0) << md.describe();
  EXPECT_TRUE(has(md.out, "6.5 [")) << md.out;
  EXPECT_TRUE(has(md.out, "IQM return")) << md.out;
  expect_one_line_error(test::run_cli({"report", dir / "runs", "--resamples", "0"}), "resamples");

  // --compare with iqm_return: a second label, its returns 10 higher, against the first.
  const std::vector<std::vector<double>> higher = {{11, 15, 19, 110}, {12, 16, 20, 14},
                                                   {13, 17, 21, 18}};
  for (int s = 0; s < 3; ++s) {
    nlohmann::json eps = nlohmann::json::array();
    for (int i = 0; i < 4; ++i)
      eps.push_back({{"index", i}, {"seed", i}, {"return", higher[s][i]}, {"length", 100}});
    put(dir / ("runs/t" + std::to_string(s)),
        {{"agent", "residual"}, {"env", "halfcheetah"}, {"episodes", eps},
         {"summary", {{"episodes", 4}, {"mean_return", 0.0}, {"mean_length", 100}}}});
  }
  CommandResult cmp = test::run_cli({"report", dir / "runs", "--json", "--compare", "residual",
                                     "bc-oh", "--compare-metric", "iqm_return"});
  ASSERT_EQ(cmp.exit_code, 0) << cmp.describe();
  const nlohmann::json row = nlohmann::json::parse(cmp.out)["compare"]["conditions"][0];
  const IqmComparison want_cmp = compare_iqm(higher, returns, 0, 10000);
  EXPECT_EQ(row["condition"], "halfcheetah");
  EXPECT_DOUBLE_EQ(row["a"].get<double>(), 16.5);  // 6.5 + 10, by hand as above
  EXPECT_DOUBLE_EQ(row["difference"].get<double>(), 10.0);
  EXPECT_DOUBLE_EQ(row["lo"].get<double>(), want_cmp.lo);
  EXPECT_DOUBLE_EQ(row["hi"].get<double>(), want_cmp.hi);
  EXPECT_EQ(row["verdict"], verdict_text(want_cmp.verdict));
  EXPECT_EQ(row["p_improvement"], 1.0);  // each residual seed is its bc-oh seed plus 10
}

// Seed 000's inertia lives in the taxonomy's fields: records from before the taxonomy give
// paper_error_rate no interval (their episodes cannot say it), newer ones do; a class the
// summary does not hold gets none either.
TEST(ReportIntervals, PaperRatesNeedTheTaxonomysFields) {
  TempDir dir("cdtest-report-paper");
  for (int s = 0; s < 3; ++s) {
    nlohmann::json old = with_episodes("old", "town-a-regular", {{"success"}, {"collision"}, {"inertia"}});
    old["summary"]["paper_error_rate"] = 2.0 / 3;
    put(dir / ("runs/old/seed" + std::to_string(s)), old);
    nlohmann::json now = with_episodes("new", "town-a-regular", {{"success"}, {"collision"}, {"stuck"}});
    now["summary"]["paper_error_rate"] = 2.0 / 3;
    now["summary"]["stuck_rate"] = 1.0 / 3;
    for (auto& e : now["episodes"]) e["taxonomy"] = {{"paper_inertia", e["outcome"] == "stuck"}};
    now["episodes"][1]["collision_kind"] = "vehicle";
    put(dir / ("runs/new/seed" + std::to_string(s)), now);
  }
  CommandResult r = test::run_cli({"report", dir / "runs", "--json"});
  ASSERT_EQ(r.exit_code, 0) << r.describe();
  const nlohmann::json doc = nlohmann::json::parse(r.out);
  int checked = 0;
  for (const auto& c : doc["cells"]) {
    if (c["metric"] == "paper_error_rate") {
      EXPECT_EQ(c.contains("lo"), c["label"] == "new") << c;
      if (c["label"] == "new") {
        EXPECT_DOUBLE_EQ(c["mean"].get<double>(), 2.0 / 3);
      }
      ++checked;
    }
    if (c["metric"] == "restart_stall_rate") {
      EXPECT_FALSE(c.contains("lo")) << c;  // not in the summary
    }
    if (c["metric"] == "stuck_rate" && c["label"] == "new") {
      EXPECT_TRUE(c.contains("lo")) << c;
    }
  }
  EXPECT_EQ(checked, 2) << r.out;
}

}  // namespace
}  // namespace cd
