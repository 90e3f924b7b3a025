// Batched inference in `eval` (issue 46): the inference process serves the worlds of an
// evaluation (eval.batch = "on"), and the results are the bytes of each world running its
// network itself (eval.batch = "off"), at any number of worlds; a world killed mid-episode is retried; a killed inference process stops
// the job with one line, and the rerun resumes to the same bytes.
// needs: sumo
#include <gtest/gtest.h>

#include <filesystem>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "../support/tiny_run.hpp"

namespace cd {
namespace {

using nlohmann::json;
namespace fs = std::filesystem;

const char* kExtra = "\n[train]\nepochs = 1\nmax_samples = 300\nthreads = 1\n";

test::TinyRun& tiny_bc_oh() {
  static test::TinyRun run({.method = "bc-oh", .traffic = "regular", .extra = kExtra});
  return run;
}

std::string config_with(test::TinyRun& run, const std::string& name, const std::string& eval) {
  const std::string path = run.dir() / name;
  test::write_text(path, test::test_config_toml("regular", std::string(kExtra) + eval, 100, 200));
  return path;
}

TEST(BatchedEval, SameBytesAtAnyNumberOfWorldsServedOrNot) {
  CD_NEEDS_SUMO();
  test::TinyRun& run = tiny_bc_oh();
  const std::string on = config_with(run, "on.toml", "\n[eval]\nbatch = \"on\"\n");
  const std::string off = config_with(run, "off.toml", "\n[eval]\nbatch = \"off\"\n");
  auto eval = [&](const std::string& config, const std::string& out, int workers) {
    test::run_cli_ok(test::eval_args(config, "bc-oh", run.run(), "quickstart", run.dir() / out,
                                     workers));
    return test::read_text(run.dir() / (out + "/results.json"));
  };
  const std::string one = eval(off, "off1", 1);  // one world running its network itself
  EXPECT_EQ(eval(on, "on3", 3), one) << "three worlds served by the inference process";
  EXPECT_EQ(eval(on, "on2", 2), one);
  EXPECT_EQ(eval(off, "off2", 2), one) << "two worlds, each running its network";
  const json res = json::parse(one);
  EXPECT_EQ(res["inference"], "batch-1");
  EXPECT_EQ(res["summary"]["episodes"], 4);
  EXPECT_EQ(res["summary"]["infrastructure_failures"], 0);

  // The inference process did serve them: bench eval at 3 workers counts its batches.
  test::CommandResult b = test::run_cli(
      {"bench", "eval", "--config", on, "--agent", "bc-oh", "--checkpoint", run.run(),
       "--suite", "quickstart", "--episodes", "3", "--workers", "3", "--rounds", "1",
       "--baseline-workers", "2", "--profile", "--json"});
  ASSERT_EQ(b.exit_code, 0) << b.describe();
  const json j = json::parse(b.out);
  EXPECT_GT(j["agent"]["batches"].get<long>(), 0);
  EXPECT_GE(j["agent"]["mean_batch"].get<double>(), 1.0);
  EXPECT_EQ(j["expert"]["batches"], 0) << "the expert has no network";
  EXPECT_EQ(j["baseline"]["batch"], "off");
  EXPECT_EQ(j["baseline"]["batches"], 0);
  EXPECT_GT(j["speedup_over_baseline"].get<double>(), 0);
  // The profile, timed in the world processes: a served world's act is its wait, which holds
  // the inference process's time for its observation.
  for (const char* row : {"agent", "expert", "baseline"}) {
    const json& p = j[row]["profile"];
    EXPECT_GT(p["world_us"].get<double>(), 0) << row;
    EXPECT_NEAR(p["step_us"].get<double>(),
                p["sense_us"].get<double>() + p["act_us"].get<double>() +
                    p["world_us"].get<double>() + p["score_us"].get<double>() +
                    p["other_us"].get<double>(),
                1e-6 * p["step_us"].get<double>() + 1e-9)
        << row;
  }
  EXPECT_GT(j["agent"]["profile"]["act_us"].get<double>(),
            j["agent"]["infer_us_per_row"].get<double>());
}

TEST(BatchedEval, AKilledWorldIsRetriedAndAKilledInferenceProcessStopsTheJob) {
  CD_NEEDS_SUMO();
  test::TinyRun& run = tiny_bc_oh();
  const std::string on = config_with(run, "on.toml", "\n[eval]\nbatch = \"on\"\n");
  auto eval_args = [&](const std::string& out) {
    return test::eval_args(on, "bc-oh", run.run(), "quickstart", run.dir() / out, 2);
  };
  run.eval("ref", 1, "quickstart");
  const std::string ref = test::read_text(run.dir() / "ref/results.json");
  {
    test::ScopedEnv crash("CAUSALDRIVE_INJECT_CRASH", "eval:1");  // episode 1's first world
    test::run_cli_ok(eval_args("world"));
  }
  EXPECT_TRUE(fs::exists(run.dir() / "world/.crash-injected-eval-1"));
  EXPECT_EQ(test::read_text(run.dir() / "world/results.json"), ref);

  test::CommandResult killed;
  {
    test::ScopedEnv crash("CAUSALDRIVE_INJECT_CRASH", "inference:40");
    killed = test::run_cli(eval_args("served"));
  }
  test::expect_one_line_error(killed, "the inference process");
  EXPECT_NE(killed.err.find("rerun"), std::string::npos) << killed.err;
  EXPECT_FALSE(fs::exists(run.dir() / "served/results.json"));
  test::run_cli_ok(eval_args("served"));
  EXPECT_EQ(test::read_text(run.dir() / "served/results.json"), ref);
}

}  // namespace
}  // namespace cd
