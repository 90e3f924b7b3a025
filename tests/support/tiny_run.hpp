#pragma once
// The CLI chains of the e2e tests, through the built binary: the argument lists of the working
// commands (collect, train, suite, eval), a check that a command succeeded, the one-line error
// contract, and TinyRun: a tiny run that collects a data folder, trains a method into a run
// folder, writes a one-task suite and evaluates the method's agent on it, each step once,
// parameterised by the method and extra config.
#include <gtest/gtest.h>

#include <cstdint>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "test_support.hpp"

namespace cd::test {

inline std::vector<std::string> with(std::vector<std::string> args,
                                     const std::vector<std::string>& more) {
  args.insert(args.end(), more.begin(), more.end());
  return args;
}

// causaldrive collect --config C --out OUT MORE...
inline std::vector<std::string> collect_args(const std::string& config, const std::string& out,
                                             const std::vector<std::string>& more = {}) {
  return with({"collect", "--config", config, "--out", out}, more);
}

// causaldrive train --config C --method M --data D --out OUT MORE...
inline std::vector<std::string> train_args(const std::string& config, const std::string& method,
                                           const std::string& data, const std::string& out,
                                           const std::vector<std::string>& more = {}) {
  return with({"train", "--config", config, "--method", method, "--data", data, "--out", out},
              more);
}

// causaldrive eval --config C --agent A [--checkpoint RUN] --suite S --workers W --out OUT
// --quiet MORE...
inline std::vector<std::string> eval_args(const std::string& config, const std::string& agent,
                                          const std::string& checkpoint, const std::string& suite,
                                          const std::string& out, int workers,
                                          const std::vector<std::string>& more = {}) {
  std::vector<std::string> a = {"eval", "--config", config, "--agent", agent};
  if (!checkpoint.empty()) a.insert(a.end(), {"--checkpoint", checkpoint});
  a.insert(a.end(), {"--suite", suite, "--workers", std::to_string(workers), "--out", out,
                     "--quiet"});
  return with(a, more);
}

// What `causaldrive suite` makes: short tasks on town-a.
struct SuiteSpec {
  std::string town = "town-a";
  std::string traffic = "regular";
  int tasks = 1, trials = 1;
  uint64_t seed = 3;
  int min_route = 100, max_route = 150;
  std::vector<std::string> scenarios = {"leader"};
};

inline std::vector<std::string> suite_args(const SuiteSpec& s, const std::string& out) {
  std::vector<std::string> a = {"suite", "--town", s.town, "--traffic", s.traffic,
                                "--tasks", std::to_string(s.tasks), "--trials",
                                std::to_string(s.trials), "--seed", std::to_string(s.seed),
                                "--min-route", std::to_string(s.min_route), "--max-route",
                                std::to_string(s.max_route), "--scenarios"};
  a.insert(a.end(), s.scenarios.begin(), s.scenarios.end());
  a.insert(a.end(), {"--out", out});
  return a;
}

// Runs the binary; throws (the test fails with the command's output) unless it exits with 0.
inline CommandResult run_cli_ok(const std::vector<std::string>& args) {
  CommandResult r = run_cli(args);
  if (!r.exited || r.exit_code != 0)
    throw std::runtime_error("causaldrive " + args.front() + " failed: " + r.describe());
  return r;
}

// Writes a suite with `causaldrive suite` and returns its path.
inline std::string write_suite(const SuiteSpec& spec, const std::string& path) {
  run_cli_ok(suite_args(spec, path));
  return path;
}

// The user-error contract: exit code 1 and exactly one line on stderr, containing `needle`.
inline void expect_one_line_error(const CommandResult& r, const std::string& needle) {
  EXPECT_TRUE(r.exited && r.exit_code == 1) << r.describe();
  EXPECT_EQ(split_lines(r.err).size(), 1u) << r.describe();
  EXPECT_NE(r.err.find(needle), std::string::npos) << r.describe();
}

inline nlohmann::json read_json(const std::string& path) {
  return nlohmann::json::parse(read_text(path));
}

inline std::vector<nlohmann::json> read_jsonl(const std::string& path) {
  std::vector<nlohmann::json> out;
  for (const auto& line : split_lines(read_text(path))) out.push_back(nlohmann::json::parse(line));
  return out;
}

struct TinyRunSpec {
  std::string method;               // trained by run() and evaluated by eval(): bc-oh, dim, cim...
  std::string traffic = "regular";  // of the test config, hence of the collected episodes
  std::string extra;                // config tables appended to the test config ([train], ...)
  SuiteSpec suite = {};             // the one-task suite of suite()
  int min_route_m = 100, max_route_m = 200;  // of the collected episodes
};

// One tiny run in a temporary folder: the test config (2 episodes) with spec.extra,
// then data/ (collected), run/ (spec.method trained on data/), suite.json, and evaluations
// into folders of their own. Each step runs once, when first needed; a failed step throws.
class TinyRun {
 public:
  explicit TinyRun(TinyRunSpec spec)
      : spec_(std::move(spec)), dir_("cdtest-tiny-" + spec_.method), config_(dir_ / "test.toml") {
    write_text(config_, test_config_toml(spec_.traffic, spec_.extra, spec_.min_route_m,
                                         spec_.max_route_m));
  }

  const TempDir& dir() const { return dir_; }
  const std::string& config() const { return config_; }

  // The collected data folder.
  const std::string& data() {
    if (data_.empty()) {
      run_cli_ok(collect_args(config_, dir_ / "data"));
      data_ = dir_ / "data";
    }
    return data_;
  }

  // spec.method's run folder, trained on data().
  const std::string& run() {
    if (run_.empty()) {
      train_ = run_cli_ok(train_args(config_, spec_.method, data(), dir_ / "run"));
      run_ = dir_ / "run";
    }
    return run_;
  }
  // What the training printed.
  const CommandResult& train_result() {
    run();
    return train_;
  }

  // The one-task suite file.
  const std::string& suite() {
    if (suite_.empty()) suite_ = write_suite(spec_.suite, dir_ / "suite.json");
    return suite_;
  }

  // Evaluates spec.method's agent on run() over `suite` (default: suite()) into dir/out_name.
  CommandResult eval(const std::string& out_name, int workers = 1, std::string suite = "") {
    if (suite.empty()) suite = this->suite();
    return run_cli_ok(eval_args(config_, spec_.method, run(), suite, dir_ / out_name, workers));
  }

  // Evaluates spec.method's agent on run() with `config` into dir/out_name, expecting the
  // one-line refusal containing `needle` and no results.json.
  CommandResult refused_eval(const std::string& config, const std::string& out_name,
                             const std::string& needle, const std::vector<std::string>& more = {}) {
    CommandResult r =
        run_cli(eval_args(config, spec_.method, run(), suite(), dir_ / out_name, 1, more));
    expect_one_line_error(r, needle);
    EXPECT_FALSE(std::filesystem::exists(dir_ / (out_name + "/results.json")));
    return r;
  }

  // dir/out_name/results.json of an evaluation.
  nlohmann::json results(const std::string& out_name) const {
    return read_json(dir_ / (out_name + "/results.json"));
  }

 private:
  TinyRunSpec spec_;
  TempDir dir_;
  std::string config_, data_, run_, suite_;
  CommandResult train_;
};

}  // namespace cd::test
