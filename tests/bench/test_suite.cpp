// The built-in benchmark suites (bench/suite): their contract, regenerating them with
// `causaldrive suite --builtin all` gives the files in the repo, a damaged suite file is one
// clear error.
#include "bench/suite.hpp"

#include <gtest/gtest.h>

#include <map>
#include <string>

#include "../support/test_support.hpp"
#include "core/error.hpp"

namespace cd {
namespace {

using test::TempDir;

TEST(BenchSuites, BuiltInSuitesMatchTheContract) {
  for (const std::string& name : builtin_suite_names()) {
    SCOPED_TRACE(name);
    Suite s = load_suite(name);
    EXPECT_EQ(s.name, name);
    ASSERT_FALSE(s.tasks.empty());
    const bool stopgo = name.size() > 7 && name.substr(name.size() - 7) == "-stopgo";
    const bool verdicts = name.rfind("verdicts-", 0) == 0;
    if (verdicts) {
      EXPECT_EQ(s.tasks.size(), 100u);
      EXPECT_EQ(s.trials, 1);
    } else if (name != "quickstart") {
      EXPECT_EQ(s.tasks.size(), 25u);
      EXPECT_EQ(s.trials, 3);
    }
    int red = 0, leader = 0;
    for (const Task& t : s.tasks) {
      if (!stopgo && name != "quickstart") {
        EXPECT_EQ(t.scenario, "route");
        EXPECT_GE(t.route_length, 300.0);
      }
      double expected = t.route_length / (5.0 / 3.6) + 20.0 + (t.scenario == "red_light" ? 60 : 0);
      EXPECT_NEAR(t.timeout_s, expected, 1e-6);
      red += t.scenario == "red_light";
      leader += t.scenario == "leader";
    }
    if (stopgo) {
      EXPECT_GE(red, 10);
      EXPECT_GE(leader, 10);
    }
  }
  EXPECT_THROW(load_suite("town-z-regular"), ConfigError);
}

// Every built-in task is its own episode: no traffic seed repeats across the suites (the
// verdicts' test suites are drawn apart from the 25-task ones).
TEST(BenchSuites, NoTwoBuiltInTasksShareATrafficSeed) {
  std::map<uint64_t, std::string> seen;
  for (const std::string& name : builtin_suite_names()) {
    const Suite suite = load_suite(name);
    for (size_t i = 0; i < suite.tasks.size(); ++i) {
      auto [it, fresh] = seen.emplace(suite.tasks[i].traffic_seed, name);
      EXPECT_TRUE(fresh) << name << " task " << i << " repeats a task of " << it->second;
    }
  }
  EXPECT_GE(seen.size(), 400u);
}

TEST(BenchSuites, RegeneratingGivesTheFilesInTheRepo) {
  CD_NEEDS_SUMO();
  TempDir dir("cdtest-suites");
  auto r = test::run_cli({"suite", "--builtin", "all", "--out", dir.path()});
  ASSERT_TRUE(r.exited && r.exit_code == 0) << r.describe();
  for (const std::string& name : builtin_suite_names()) {
    SCOPED_TRACE(name);
    EXPECT_EQ(test::read_text(dir / (name + ".json")),
              test::read_text(std::string(CD_SOURCE_DIR) + "/suites/" + name + ".json"));
  }
}

TEST(BenchSuites, DamagedSuiteFileIsOneClearError) {
  CD_NEEDS_SUMO();
  TempDir dir("cdtest-suites");
  test::write_text(dir / "bad.json", "{\"format\": 1, \"name\": \"x\"");
  auto r = test::run_cli({"eval", "--agent", "expert", "--suite", dir / "bad.json", "--out",
                          dir / "out"});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_EQ(test::split_lines(r.err).size(), 1u) << r.err;
  EXPECT_NE(r.err.find("bad.json"), std::string::npos);
  test::write_text(dir / "nokey.json", "{\"format\": 1, \"name\": \"x\", \"town\": \"town-a\"}");
  r = test::run_cli({"eval", "--agent", "expert", "--suite", dir / "nokey.json", "--out",
                     dir / "out2"});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("traffic"), std::string::npos) << r.err;
}

}  // namespace
}  // namespace cd
