// `causaldrive granger --input CSV|RUN_DIR --target Y [--lags L] [--alpha A] [--episode-col C]
// [--correction none|bonferroni|bh] [--variables a,b] [--conditional] [--json]`: Granger-causality
// F tests of candidate variables against a target (SPEC section 4, causal/granger.hpp).
#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <set>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "causal/granger.hpp"
#include "causal/series_csv.hpp"
#include "cli/commands.hpp"
#include "core/error.hpp"

namespace cd::cli {

namespace {

namespace fs = std::filesystem;

struct GrangerArgs {
  std::string input, target, episode_col, correction = "none", variables;
  int lags = 3;
  double alpha = 0.05;
  bool conditional = false, json = false;
};

std::string join(const std::vector<std::string>& names) {
  std::string s;
  for (const std::string& n : names) s += (s.empty() ? "" : ", ") + n;
  return s;
}

// "a, b,c" -> {"a", "b", "c"}; empty items are an error.
std::vector<std::string> split_list(const std::string& text) {
  std::vector<std::string> out;
  size_t start = 0;
  while (true) {
    size_t comma = text.find(',', start);
    std::string item = text.substr(start, comma == std::string::npos ? std::string::npos : comma - start);
    size_t a = item.find_first_not_of(" \t"), b = item.find_last_not_of(" \t");
    item = a == std::string::npos ? "" : item.substr(a, b - a + 1);
    if (item.empty()) throw ConfigError("granger: --variables '" + text + "' has an empty name");
    out.push_back(item);
    if (comma == std::string::npos) break;
    start = comma + 1;
  }
  return out;
}

void run_granger(GrangerArgs a) {
  if (a.input.empty())
    throw ConfigError("granger: --input is required (a CSV file, or a run folder holding series.csv)");
  std::error_code ec;
  std::string csv = a.input;
  if (fs::is_directory(a.input, ec)) {
    // A run folder of the cim pipeline: its series.csv, with that file's column names.
    csv = (fs::path(a.input) / "series.csv").string();
    if (!fs::is_regular_file(csv, ec))
      throw IoError("granger: --input " + a.input + " is a folder without series.csv");
    if (a.target.empty()) a.target = "speed";
    if (a.episode_col.empty()) a.episode_col = "episode";
  } else if (!fs::exists(a.input, ec)) {
    throw IoError("granger: --input " + a.input + ": no such file or folder");
  } else if (a.target.empty()) {
    throw ConfigError("granger: --target is required when --input is a CSV file");
  }
  if (a.lags < 1) throw ConfigError("granger: --lags must be at least 1, got " + std::to_string(a.lags));
  if (!(a.alpha > 0 && a.alpha <= 1))
    throw ConfigError("granger: --alpha must be in (0, 1], got " + std::to_string(a.alpha));
  adjust_p_values({}, a.correction);  // an unknown correction fails before reading the data

  SeriesTable table = read_series_csv(csv, a.episode_col);
  if (!table.has(a.target)) {
    throw ConfigError("granger: no target column '" + a.target + "' in " + csv +
                      " (columns: " + join(table.columns) + ")");
  }
  std::vector<std::string> names;
  if (a.variables.empty()) {
    for (const std::string& c : table.columns)
      if (c != a.target) names.push_back(c);
  } else {
    std::set<std::string> seen;
    for (const std::string& v : split_list(a.variables)) {
      if (v == a.target) throw ConfigError("granger: --variables names the target '" + v + "'");
      if (!table.has(v))
        throw ConfigError("granger: no column '" + v + "' in " + csv + " (columns: " +
                          join(table.columns) + ")");
      if (!seen.insert(v).second) throw ConfigError("granger: --variables names '" + v + "' twice");
      names.push_back(v);
    }
  }
  if (names.empty())
    throw ConfigError("granger: no candidate variables in " + csv + " besides the target '" +
                      a.target + "'");
  std::vector<NamedSeries> candidates;
  for (const std::string& n : names) candidates.push_back({n, table.column(n)});

  std::vector<GrangerResult> results = granger_select(table.column(a.target), candidates, a.lags,
                                                      a.alpha, a.correction, a.conditional);

  if (a.json) {
    nlohmann::json out = nlohmann::json::array();
    for (const GrangerResult& r : results)
      out.push_back({{"variable", r.variable},
                     {"f_stat", r.test.f_stat},
                     {"p_value", r.test.p_value},
                     {"p_adjusted", r.p_adjusted},
                     {"df_num", r.test.df_num},
                     {"df_den", r.test.df_den},
                     {"partial_r2", r.test.partial_r2},
                     {"selected", r.selected}});
    std::string text = out.dump(2) + "\n";
    std::fwrite(text.data(), 1, text.size(), stdout);
    std::fflush(stdout);
    return;
  }

  size_t width = 8;
  for (const std::string& n : names) width = std::max(width, n.size());
  const GrangerTest& first = results.front().test;
  std::printf("Granger causality -> %s: %d lags, %ld rows in %zu episode(s)%s\n", a.target.c_str(),
              a.lags, first.rows, table.episode_ids.size(),
              a.conditional ? ", each candidate conditioned on the others" : "");
  std::printf("%-*s  %12s  %12s  %12s  %12s  %12s  %s\n", static_cast<int>(width), "variable", "F",
              "df", "p", "p adjusted", "partial R2", "selected");
  int selected = 0;
  for (const GrangerResult& r : results) {
    std::string df = std::to_string(r.test.df_num) + "," + std::to_string(r.test.df_den);
    // The mark in the "selected" column, no trailing blanks on the other rows.
    std::printf("%-*s  %12.4f  %12s  %12.4g  %12.4g  %12.4g%s\n", static_cast<int>(width),
                r.variable.c_str(), r.test.f_stat, df.c_str(), r.test.p_value, r.p_adjusted,
                r.test.partial_r2, r.selected ? "  *" : "");
    selected += r.selected ? 1 : 0;
  }
  std::printf("selected: %d of %zu at alpha %g (correction %s)\n", selected, results.size(),
              a.alpha, a.correction.c_str());
  std::fflush(stdout);
}

}  // namespace

void add_granger(CLI::App& app) {
  auto args = std::make_shared<GrangerArgs>();
  CLI::App* sub = app.add_subcommand(
      "granger", "Granger-causality F tests of candidate variables against a target");
  sub->add_option("--input,-i", args->input,
                  "a CSV file with a header row, or a run folder holding series.csv (then the "
                  "defaults are --target speed --episode-col episode)")
      ->type_name("CSV|DIR");
  sub->add_option("--target", args->target, "the target column Y (required for a CSV file)")
      ->type_name("COLUMN");
  sub->add_option("--lags", args->lags, "lags L of both series in the regressions (default 3)");
  sub->add_option("--alpha", args->alpha,
                  "level at which a variable is selected, in (0, 1] (default 0.05)");
  sub->add_option("--episode-col", args->episode_col,
                  "column naming the episode; rows never take lags across episodes (default: "
                  "none, the whole file is one episode)")
      ->type_name("COLUMN");
  sub->add_option("--correction", args->correction,
                  "multiple-testing correction: none | bonferroni | bh (default none)")
      ->type_name("METHOD");
  sub->add_option("--variables", args->variables,
                  "comma-separated candidate columns (default: all but the target and episode "
                  "column)")
      ->type_name("A,B,...");
  sub->add_flag("--conditional", args->conditional,
                "test each candidate conditioning on all the other candidates");
  sub->add_flag("--json", args->json,
                "print one JSON array (variable, f_stat, p_value, p_adjusted, df_num, df_den, "
                "partial_r2, selected) and nothing else");
  // Validated in run_granger rather than by CLI11 so that every user error is one line, exit 1.
  sub->callback([args] { run_granger(*args); });
}

}  // namespace cd::cli
