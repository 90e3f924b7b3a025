// `causaldrive eval` end to end with the expert and cs agents: the results' contract keys,
// determinism whatever the worker count, resume after kill -9, crashed episodes retried and
// never counted as policy failures, one-line errors.
// needs: sumo
#include <gtest/gtest.h>
#include <signal.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <sstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "../support/tiny_run.hpp"

namespace cd {
namespace {

using test::read_json;
using test::TempDir;
namespace fs = std::filesystem;

// A suite of short tasks with traffic, made with the CLI like a user would.
std::string make_small_suite(const TempDir& dir, int tasks) {
  return test::write_suite({.traffic = "regular",
                            .tasks = tasks,
                            .seed = 5,
                            .min_route = 150,
                            .max_route = 250,
                            .scenarios = {"route", "red_light", "leader"}},
                           dir / "small.json");
}

test::CommandResult eval_cli(const std::string& config, const std::string& suite,
                             const std::string& out, const std::string& agent = "expert",
                             int workers = 2) {
  return test::run_cli(test::eval_args(config, agent, "", suite, out, workers));
}

TEST(BenchEval, ResultsHaveTheContractKeysAndTheExpertSucceeds) {
  TempDir dir("cdtest-eval");
  const std::string cfg = test::write_test_config(dir);
  auto r = eval_cli(cfg, "quickstart", dir / "out");
  ASSERT_TRUE(r.exited && r.exit_code == 0) << r.describe();
  EXPECT_NE(r.out.find("| expert | quickstart |"), std::string::npos) << r.out;
  nlohmann::json res = read_json(dir / "out/results.json");
  EXPECT_EQ(res["agent"], "expert");
  EXPECT_EQ(res["suite"], "quickstart");
  ASSERT_EQ(res["episodes"].size(), 4u);
  const nlohmann::json& s = res["summary"];
  for (const char* k : {"success_rate", "collision_rate", "inertia_rate", "timeout_rate",
                        "error_rate", "stall_rate", "route_completion"}) {
    ASSERT_TRUE(s.contains(k)) << k;
    EXPECT_GE(s[k].get<double>(), 0.0) << k;
    EXPECT_LE(s[k].get<double>(), 1.0) << k;
  }
  for (const char* k : {"stop_go_events", "start_delay_median_s", "start_delay_p90_s",
                        "red_light_violations_per_km", "mean_speed"})
    EXPECT_TRUE(s.contains(k)) << k;
  EXPECT_DOUBLE_EQ(s["success_rate"].get<double>(), 1.0);
  EXPECT_DOUBLE_EQ(s["error_rate"].get<double>(),
                   s["collision_rate"].get<double>() + s["inertia_rate"].get<double>());
  // The red-light and leader tasks make stop-and-go events; the expert never stalls.
  EXPECT_GE(s["stop_go_events"].get<int>(), 2);
  EXPECT_EQ(s["stalls"].get<int>(), 0);
  for (const auto& e : res["episodes"]) EXPECT_EQ(e["outcome"], "success");
}

// --trace: one line per agent step; a free-steering ego (the default) adds its steer, pose and
// lane errors, whose positions advance by the speed times dt; a route-mode ego has none of them.
TEST(BenchEval, TraceHasOneLinePerStepAndAFreeEgosSteerAndPose) {
  TempDir dir("cdtest-eval");
  for (const std::string mode : {"free", "route"}) {
    const std::string cfg = test::write_test_config(
        dir, "regular", "\n[ego]\nlateral = \"" + mode + "\"\n", mode + ".toml");
    std::vector<std::string> args = test::eval_args(cfg, "expert", "", "quickstart", dir / mode, 2);
    args.push_back("--trace");
    auto r = test::run_cli(args);
    ASSERT_TRUE(r.exited && r.exit_code == 0) << r.describe();
    const nlohmann::json res = read_json(dir / (mode + "/results.json"));
    const std::string text = test::read_text(dir / (mode + "/episodes/episode_000000.trace.csv"));
    std::vector<std::vector<std::string>> rows;
    std::stringstream lines(text);
    for (std::string line; std::getline(lines, line);) {
      std::vector<std::string> row;
      std::stringstream fields(line);
      for (std::string f; std::getline(fields, f, ',');) row.push_back(f);
      rows.push_back(row);
    }
    ASSERT_GT(rows.size(), 10u) << text.substr(0, 500);
    const std::vector<std::string>& head = rows[0];
    auto col = [&](const std::string& name) {
      return static_cast<int>(std::find(head.begin(), head.end(), name) - head.begin());
    };
    EXPECT_EQ(col("tl_state"), static_cast<int>(head.size()) - 1) << "causes last";
    // One line per step of the episode after the prefill: its duration over dt (0.1 s).
    EXPECT_NEAR(double(rows.size() - 1), res["episodes"][0]["duration_s"].get<double>() / 0.1, 1.5);
    for (size_t i = 1; i < rows.size(); ++i) ASSERT_EQ(rows[i].size(), head.size()) << i;
    if (mode == "route") {
      EXPECT_EQ(col("steer"), static_cast<int>(head.size())) << "no steer column in route mode";
      continue;
    }
    const int steer = col("steer"), x = col("x"), y = col("y"), speed = col("speed"),
              lat = col("lateral_error_m");
    ASSERT_EQ(steer, 6);
    ASSERT_EQ(lat, 10);
    double most = 0;
    for (size_t i = 1; i + 1 < rows.size(); ++i) {
      const double s = std::stod(rows[i][steer]);
      EXPECT_LE(std::abs(s), 1.0);
      most = std::max(most, std::abs(s));
      EXPECT_LT(std::abs(std::stod(rows[i][lat])), 1.0) << "the expert keeps its lane";
      // The next step's position: this speed to the next one over 0.1 s (m, 2 decimals).
      const double moved = std::hypot(std::stod(rows[i + 1][x]) - std::stod(rows[i][x]),
                                      std::stod(rows[i + 1][y]) - std::stod(rows[i][y]));
      const double v0 = std::stod(rows[i][speed]), v1 = std::stod(rows[i + 1][speed]);
      EXPECT_NEAR(moved, 0.05 * (v0 + v1), 0.02) << "step " << i;
    }
    EXPECT_GT(most, 0.05) << "the expert never steered";
  }
}

TEST(BenchEval, SameSeedSameBytesWhateverTheWorkerCount) {
  TempDir dir("cdtest-eval");
  const std::string cfg = test::write_test_config(dir);
  const std::string suite = make_small_suite(dir, 4);
  auto a = eval_cli(cfg, suite, dir / "a", "cs", 1);
  auto b = eval_cli(cfg, suite, dir / "b", "cs", 2);
  ASSERT_EQ(a.exit_code, 0) << a.describe();
  ASSERT_EQ(b.exit_code, 0) << b.describe();
  EXPECT_EQ(test::read_text(dir / "a/results.json"), test::read_text(dir / "b/results.json"));
}

TEST(BenchEval, KilledRunResumesWithNothingLostOrCountedTwice) {
  TempDir dir("cdtest-eval");
  const std::string cfg = test::write_test_config(dir, "regular");
  const std::string suite = make_small_suite(dir, 9);
  auto ref = eval_cli(cfg, suite, dir / "ref", "expert", 1);
  ASSERT_EQ(ref.exit_code, 0) << ref.describe();

  // kill -9 of the command and its workers once episode 2's record is written (the hook of
  // core/fault.hpp): three episodes recorded, no results.
  {
    test::ScopedEnv crash("CAUSALDRIVE_INJECT_CRASH", "eval-recorded:2");
    auto killed = eval_cli(cfg, suite, dir / "run", "expert", 1);
    ASSERT_TRUE(!killed.exited && killed.signal == SIGKILL) << killed.describe();
  }
  EXPECT_FALSE(fs::exists(dir / "run/results.json"));
  std::vector<std::string> records;
  for (const auto& n : test::list_dir(dir / "run/episodes"))
    if (test::ends_with(n, ".json")) records.push_back(n);
  EXPECT_EQ(records, (std::vector<std::string>{"episode_000000.json", "episode_000001.json",
                                               "episode_000002.json"}));

  auto again = eval_cli(cfg, suite, dir / "run", "expert", 1);
  ASSERT_EQ(again.exit_code, 0) << again.describe();
  EXPECT_NE(again.out.find("episodes run now"), std::string::npos);
  EXPECT_EQ(test::read_text(dir / "run/results.json"), test::read_text(dir / "ref/results.json"));
  nlohmann::json res = read_json(dir / "run/results.json");
  ASSERT_EQ(res["episodes"].size(), 9u);
  for (int i = 0; i < 9; ++i) EXPECT_EQ(res["episodes"][i]["index"], i);
}

TEST(BenchEval, CrashedEpisodeIsRetriedAndNeverCountedAsAPolicyFailure) {
  TempDir dir("cdtest-eval");
  const std::string cfg = test::write_test_config(dir);
  auto ref = eval_cli(cfg, "quickstart", dir / "ref");
  ASSERT_EQ(ref.exit_code, 0) << ref.describe();

  // The hook of core/fault.hpp kills an episode's process as it starts.
  test::CommandResult once, always;
  {
    test::ScopedEnv crash("CAUSALDRIVE_INJECT_CRASH", "eval:1");  // the first run of episode 1
    once = eval_cli(cfg, "quickstart", dir / "once");
  }
  {
    test::ScopedEnv crash("CAUSALDRIVE_INJECT_CRASH", "eval:2:always");  // every run of episode 2
    always = eval_cli(cfg, "quickstart", dir / "always");
  }

  ASSERT_EQ(once.exit_code, 0) << once.describe();
  EXPECT_TRUE(fs::exists(dir / "once/.crash-injected-eval-1"));
  EXPECT_EQ(test::read_text(dir / "once/results.json"), test::read_text(dir / "ref/results.json"));

  ASSERT_EQ(always.exit_code, 0) << always.describe();
  EXPECT_NE(always.err.find("not counted"), std::string::npos) << always.err;
  nlohmann::json res = read_json(dir / "always/results.json");
  EXPECT_EQ(res["summary"]["infrastructure_failures"], 1);
  EXPECT_EQ(res["summary"]["episodes"], 3);
  EXPECT_DOUBLE_EQ(res["summary"]["success_rate"].get<double>(), 1.0);
  EXPECT_EQ(res["episodes"][2]["outcome"], "infrastructure_failure");
  // The next run retries it, and then the results are complete.
  auto retry = eval_cli(cfg, "quickstart", dir / "always");
  ASSERT_EQ(retry.exit_code, 0) << retry.describe();
  EXPECT_EQ(test::read_text(dir / "always/results.json"), test::read_text(dir / "ref/results.json"));
}

TEST(BenchEval, BadRequestsGiveOneLineAndExitOne) {
  TempDir dir("cdtest-eval");
  const std::string cfg = test::write_test_config(dir);
  auto check = [&](const std::vector<std::string>& args, const std::string& needle) {
    auto r = test::run_cli(args);
    EXPECT_TRUE(r.exited && r.exit_code == 1) << r.describe();
    EXPECT_EQ(test::split_lines(r.err).size(), 1u) << r.err;
    EXPECT_NE(r.err.find(needle), std::string::npos) << r.err;
  };
  check({"eval", "--config", cfg, "--agent", "nobody", "--out", dir / "o1"}, "unknown agent");
  check({"eval", "--config", cfg, "--agent", "expert", "--suite", "town-q-dense", "--out",
         dir / "o2"},
        "unknown suite");
  check({"eval", "--config", cfg, "--agent", "bc-oh", "--out", dir / "o3"}, "--checkpoint");
  check({"eval", "--config", cfg, "--agent", "bc-oh", "--checkpoint", dir / "missing", "--out",
         dir / "o4"},
        "missing");
  // A folder holding another agent's run is not overwritten.
  auto r = eval_cli(cfg, "quickstart", dir / "o5");
  ASSERT_EQ(r.exit_code, 0) << r.describe();
  const std::string before = test::read_text(dir / "o5/results.json");
  check({"eval", "--config", cfg, "--agent", "cs", "--out", dir / "o5"}, "another evaluation");
  EXPECT_EQ(test::read_text(dir / "o5/results.json"), before);
}

// eval.sensor: results.json says which sensor the agents had; the privileged expert never
// sees the shift (same episodes); a folder of one sensor is not resumed with the other; a bad
// value is one line naming the key. Every eval records the traffic-light passages.
TEST(BenchEval, SensorIsRecordedTheExpertNeverSeesTheShiftAndFoldersDoNotMix) {
  TempDir dir("cdtest-eval");
  const std::string clean = test::write_test_config(dir);
  const std::string shifted = test::write_test_config(
      dir, "empty", "\n[eval]\nsensor = \"shifted\"\nsensor_seed = 4\n", "shifted.toml");
  auto a = eval_cli(clean, "quickstart", dir / "clean");
  auto b = eval_cli(shifted, "quickstart", dir / "shifted");
  ASSERT_EQ(a.exit_code, 0) << a.describe();
  ASSERT_EQ(b.exit_code, 0) << b.describe();
  EXPECT_NE(b.out.find("| expert | quickstart (shifted sensor) |"), std::string::npos) << b.out;
  nlohmann::json ra = read_json(dir / "clean/results.json");
  nlohmann::json rb = read_json(dir / "shifted/results.json");
  EXPECT_EQ(ra["sensor"], "clean");
  EXPECT_FALSE(ra.contains("sensor_shift"));
  EXPECT_EQ(rb["sensor"], "shifted");
  EXPECT_EQ(rb["sensor_shift"]["seed"], 4);
  EXPECT_DOUBLE_EQ(rb["sensor_shift"]["miss"].get<double>(), 0.15);
  EXPECT_EQ(ra["episodes"], rb["episodes"]) << "the expert drives on the world, not the BEV";
  EXPECT_EQ(ra["summary"], rb["summary"]);

  // Light passages: the red-light start is one at least; the rate is the pooled share.
  const nlohmann::json& s = ra["summary"];
  int passages = 0, green = 0;
  for (const auto& e : ra["episodes"]) {
    EXPECT_LE(e["green_light_entries"].get<int>(), e["light_passages"].get<int>());
    EXPECT_EQ(e["red_light_violations"], 0) << "the expert runs no red light";
    passages += e["light_passages"].get<int>();
    green += e["green_light_entries"].get<int>();
  }
  EXPECT_GE(passages, 1) << "the quickstart suite's red-light task passes a light";
  EXPECT_EQ(s["light_passages"], passages);
  EXPECT_EQ(s["green_light_entries"], green);
  EXPECT_DOUBLE_EQ(s["green_light_rate"].get<double>(), double(green) / passages);

  auto refused = test::run_cli(test::eval_args(shifted, "expert", "", "quickstart", dir / "clean", 1));
  EXPECT_EQ(refused.exit_code, 1) << refused.describe();
  EXPECT_EQ(test::split_lines(refused.err).size(), 1u) << refused.err;
  EXPECT_NE(refused.err.find("another evaluation (sensor"), std::string::npos) << refused.err;

  // The device eval.device resolved to is part of the folder's claim: a folder begun on a GPU
  // is not resumed on the CPU (its episodes would mix two devices); one written before the
  // device was recorded counts as a CPU run.
  EXPECT_EQ(ra["device"], "cpu");
  nlohmann::json claim = read_json(dir / "clean/run.json");
  EXPECT_EQ(claim["device"], "cpu");
  claim["device"] = "cuda";
  test::write_text(dir / "clean/run.json", claim.dump(2) + "\n");
  auto other = test::run_cli(test::eval_args(clean, "expert", "", "quickstart", dir / "clean", 1));
  EXPECT_EQ(other.exit_code, 1) << other.describe();
  EXPECT_EQ(test::split_lines(other.err).size(), 1u) << other.err;
  EXPECT_NE(other.err.find("another evaluation (device \"cuda\", now \"cpu\")"),
            std::string::npos)
      << other.err;
  claim.erase("device");
  test::write_text(dir / "clean/run.json", claim.dump(2) + "\n");
  auto old = test::run_cli(test::eval_args(clean, "expert", "", "quickstart", dir / "clean", 1));
  EXPECT_EQ(old.exit_code, 0) << old.describe();

  // Each episode record keeps what decides a timeout's class; a folder whose records predate
  // the taxonomy (SPEC section 14) is not resumed: one line asks for a new folder.
  nlohmann::json first = read_json(dir / "clean/episodes/episode_000000.json");
  ASSERT_TRUE(first.contains("taxonomy")) << first.dump();
  EXPECT_EQ(first["taxonomy"]["final_max_speed"].size(), 15u) << first.dump();
  EXPECT_FALSE(first["taxonomy"]["paper_inertia"].get<bool>());
  first.erase("taxonomy");
  test::write_text(dir / "clean/episodes/episode_000000.json", first.dump() + "\n");
  auto before = test::run_cli(test::eval_args(clean, "expert", "", "quickstart", dir / "clean", 1));
  EXPECT_EQ(before.exit_code, 1) << before.describe();
  EXPECT_EQ(test::split_lines(before.err).size(), 1u) << before.err;
  EXPECT_NE(before.err.find("episode_000000.json was evaluated before the failure taxonomy"),
            std::string::npos)
      << before.err;

  const std::string bad = test::write_test_config(dir, "empty", "\n[eval]\nsensor = \"rainy\"\n",
                                                  "bad.toml");
  auto r = test::run_cli(test::eval_args(bad, "expert", "", "quickstart", dir / "bad", 1));
  EXPECT_EQ(r.exit_code, 1) << r.describe();
  ASSERT_EQ(test::split_lines(r.err).size(), 1u) << r.err;
  EXPECT_NE(r.err.find("eval.sensor"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("rainy"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir / "bad")) << "nothing written on a config error";
}

}  // namespace
}  // namespace cd

namespace cd {
namespace {

// The expert drove into a pedestrian in a free-mode episode of the built-in suites (town-b
// regular task 10 trial 1, ped27): turning, its body off the path, the pedestrian dropped out of
// the path test for a step and it accelerated into them. That episode, as the built-in suite
// draws it, ends in success now (and so does the task's trial 0). In task 13 trial 2 it crept
// towards a pedestrian waiting at the kerb beside its left turn (ped31), stopped 1 m from it,
// and each waited for the other until SUMO's walker gave up waiting and walked into it: all
// three trials end in success now.
TEST(BenchEval, ExpertStopsForPedestriansAheadOfItsBodyInTurns) {
  TempDir dir("cdtest-eval-peds");
  struct Case {
    const char* suite;
    int task, trials;
  };
  for (const Case& c : {Case{"town-b-regular", 10, 2}, Case{"town-b-regular", 13, 3}}) {
    nlohmann::json suite =
        read_json(std::string(CD_SOURCE_DIR) + "/suites/" + c.suite + ".json");
    suite["tasks"] = nlohmann::json::array({suite["tasks"][c.task]});
    suite["name"] = std::string(c.suite) + "-task";
    const std::string file = dir / (std::string(c.suite) + ".json");
    test::write_text(file, suite.dump());
    const std::string out = dir / (std::string(c.suite) + "-" + std::to_string(c.task));
    auto r = test::run_cli({"eval", "--agent", "expert", "--suite", file, "--trials",
                            std::to_string(c.trials), "--workers", "1", "--out", out, "--quiet"});
    ASSERT_TRUE(r.exited && r.exit_code == 0) << r.describe();
    const nlohmann::json res = read_json(out + "/results.json");
    ASSERT_EQ(res["episodes"].size(), static_cast<size_t>(c.trials));
    for (const auto& e : res["episodes"])
      EXPECT_EQ(e["outcome"], "success") << c.suite << " trial " << e["trial"] << ": " << e.dump();
  }
}

}  // namespace
}  // namespace cd
