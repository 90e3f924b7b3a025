// Jobs under mpirun (SPEC section 12), through the built binary: `mpirun -np 3 causaldrive eval`
// and `collect` write the bytes of `--workers 2`; a job killed mid-way resumes under either
// launcher to the uninterrupted run's bytes; a failing episode is named with its rank and
// host; commands that do not spread are refused. At most 3 ranks, --oversubscribe; ctest runs
// nothing beside these (RUN_SERIAL). Skipped when the build has no MPI.
//
// And the run folder's lock through the CLI (suite RunLockCli): a second eval into a held
// folder, a concurrent train, a stale lock.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <map>
#include <string>
#include <thread>
#include <vector>

#include "../support/tiny_run.hpp"
#include "core/mpi.hpp"
#include "core/run_lock.hpp"

namespace cd {
namespace {

using test::TempDir;
namespace fs = std::filesystem;

// The environment OpenMPI needs in a container run as root, for the life of a test.
struct MpiEnv {
  test::ScopedEnv root{"OMPI_ALLOW_RUN_AS_ROOT", "1"};
  test::ScopedEnv confirm{"OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1"};
  test::ScopedEnv cma{"OMPI_MCA_btl_vader_single_copy_mechanism", "none"};
};

std::string mpirun_path() {
  for (const char* p : {"/usr/bin/mpirun", "/usr/local/bin/mpirun"})
    if (fs::exists(p)) return p;
  return "";
}

// Each MPI test: skipped without MPI, OpenMPI's environment set, a temporary folder.
class MpiJobs : public testing::Test {
 protected:
  void SetUp() override {
    if (!mpi_compiled() || mpirun_path().empty()) GTEST_SKIP() << "no MPI in this build";
  }
  MpiEnv env;
  TempDir dir{"cdtest-mpi"};
};

test::CommandResult mpirun(int ranks, const std::vector<std::string>& args) {
  std::vector<std::string> argv = {mpirun_path(), "--oversubscribe", "-np", std::to_string(ranks),
                                   CD_BINARY};
  argv.insert(argv.end(), args.begin(), args.end());
  return test::run_command(argv);
}

std::string small_suite(const TempDir& dir, int tasks) {
  return test::write_suite({.traffic = "regular", .tasks = tasks, .seed = 5, .min_route = 150,
                            .max_route = 250, .scenarios = {"route", "red_light", "leader"}},
                           dir / "small.json");
}

// Every file of a folder tree (relative path -> bytes), the lock and crash markers aside.
std::map<std::string, std::string> tree_bytes(const std::string& root) {
  std::map<std::string, std::string> out;
  for (const auto& e : fs::recursive_directory_iterator(root)) {
    if (!e.is_regular_file()) continue;
    const std::string name = e.path().filename().string();
    if (name.rfind(".crash-injected", 0) == 0 || name == kRunLockName) continue;
    out[fs::relative(e.path(), root).string()] = test::read_text(e.path().string());
  }
  return out;
}

TEST_F(MpiJobs, EvalAndCollectOnThreeRanksWriteTheBytesOfTwoWorkers) {
  CD_NEEDS_SUMO();
  const std::string cfg = test::write_test_config(dir, "regular");
  const std::string suite = small_suite(dir, 5);
  test::run_cli_ok(test::eval_args(cfg, "cs", "", suite, dir / "workers", 2));
  auto m = mpirun(3, test::eval_args(cfg, "cs", "", suite, dir / "mpi", 1));
  ASSERT_TRUE(m.exited && m.exit_code == 0) << m.describe();
  EXPECT_NE(m.out.find("| cs |"), std::string::npos) << "rank 0 prints the table";
  EXPECT_EQ(m.out.find("| cs |"), m.out.rfind("| cs |")) << "only rank 0 prints: " << m.out;
  const auto a = tree_bytes(dir / "workers"), b = tree_bytes(dir / "mpi");
  EXPECT_EQ(a.size(), 7u);  // results.json, run.json, 5 episode records
  EXPECT_TRUE(a == b) << "eval under mpirun differs from --workers 2";

  test::run_cli_ok(test::collect_args(cfg, dir / "data-workers", {"--workers", "2"}));
  auto c = mpirun(3, test::collect_args(cfg, dir / "data-mpi", {"--workers", "1"}));
  ASSERT_TRUE(c.exited && c.exit_code == 0) << c.describe();
  auto x = tree_bytes(dir / "data-workers"), y = tree_bytes(dir / "data-mpi");
  EXPECT_GE(x.size(), 3u);
  // The manifest records the settings, the folder and worker count among them.
  auto manifest = [](std::map<std::string, std::string>& files) {
    nlohmann::json m = nlohmann::json::parse(files.at("collect.json"));
    m["settings"]["collect"].erase("out");
    m["settings"]["collect"].erase("workers");
    files.erase("collect.json");
    return m;
  };
  EXPECT_EQ(manifest(x), manifest(y));
  EXPECT_TRUE(x == y) << "collect's episodes under mpirun differ from --workers 2";
}

// A learned agent: on 2 ranks each world runs its network itself, served by one inference
// process (eval.batch = "on") 3 worlds share it; the same bytes (batch-invariant kernels).
TEST_F(MpiJobs, ALearnedAgentOnTwoRanksWritesTheBytesOfServedWorlds) {
  CD_NEEDS_SUMO();
  test::TinyRun run({.method = "bc-oh",
                     .traffic = "regular",
                     .extra = "\n[train]\nepochs = 1\nmax_samples = 300\nthreads = 1\n"
                              "\n[eval]\nbatch = \"on\"\n"});
  run.eval("served", 3, "quickstart");
  auto m = mpirun(2, test::eval_args(run.config(), "bc-oh", run.run(), "quickstart",
                                     run.dir() / "mpi", 1));
  ASSERT_TRUE(m.exited && m.exit_code == 0) << m.describe();
  EXPECT_EQ(test::read_text(run.dir() / "mpi/results.json"),
            test::read_text(run.dir() / "served/results.json"));
}

TEST_F(MpiJobs, AKilledJobResumesUnderEitherLauncherToTheUninterruptedBytes) {
  CD_NEEDS_SUMO();
  const std::string cfg = test::write_test_config(dir, "regular");
  const std::string suite = small_suite(dir, 7);
  test::run_cli_ok(test::eval_args(cfg, "expert", "", suite, dir / "ref", 2));
  for (const std::string resume : {"mpirun", "workers"}) {
    const std::string out = dir / ("run-" + resume);
    {
      // The rank that has written episode 4's record dies with its process group, mid-job.
      test::ScopedEnv crash("CAUSALDRIVE_INJECT_CRASH", "eval-recorded:4");
      auto killed = mpirun(3, test::eval_args(cfg, "expert", "", suite, out, 1));
      ASSERT_FALSE(killed.exited && killed.exit_code == 0) << killed.describe();
    }
    EXPECT_FALSE(fs::exists(out + "/results.json")) << "no summary from a killed job";
    EXPECT_TRUE(fs::exists(out + "/episodes/episode_000004.json"));
    auto again = resume == "mpirun" ? mpirun(3, test::eval_args(cfg, "expert", "", suite, out, 1))
                                    : test::run_cli(test::eval_args(cfg, "expert", "", suite, out, 2));
    ASSERT_TRUE(again.exited && again.exit_code == 0) << resume << ": " << again.describe();
    EXPECT_TRUE(tree_bytes(out) == tree_bytes(dir / "ref")) << "resumed by " << resume;
  }
}

TEST_F(MpiJobs, AFailingEpisodeIsNamedWithItsRankAndHost) {
  CD_NEEDS_SUMO();
  const std::string cfg = test::write_test_config(dir);
  test::ScopedEnv crash("CAUSALDRIVE_INJECT_CRASH", "eval:2:always");  // every run of episode 2
  auto r = mpirun(2, test::eval_args(cfg, "expert", "", "quickstart", dir / "out", 1));
  ASSERT_TRUE(r.exited && r.exit_code == 0) << r.describe();
  // Episode 2 is rank 0's (episodes 0 and 2 of 0..3): the recorded failure names it.
  const nlohmann::json res = test::read_json(dir / "out/results.json");
  EXPECT_EQ(res["episodes"][2]["outcome"], "infrastructure_failure");
  const std::string why = res["episodes"][2]["failure"];
  char host[256] = {0};
  ::gethostname(host, sizeof host - 1);
  EXPECT_NE(why.find(std::string("rank 0 of 2 on ") + host + ": job 2: "), std::string::npos) << why;
}

TEST_F(MpiJobs, EachFailedEpisodeCarriesTheLineOfItsOwnRank) {
  CD_NEEDS_SUMO();
  const std::string cfg = test::write_test_config(dir);
  // Episode 1 is rank 1's, episode 2 rank 0's (episodes 0..3 dealt over 2 ranks).
  test::ScopedEnv crash("CAUSALDRIVE_INJECT_CRASH", "eval:1:always,eval:2:always");
  auto r = mpirun(2, test::eval_args(cfg, "expert", "", "quickstart", dir / "out", 1));
  ASSERT_TRUE(r.exited && r.exit_code == 0) << r.describe();
  const nlohmann::json res = test::read_json(dir / "out/results.json");
  char host[256] = {0};
  ::gethostname(host, sizeof host - 1);
  for (int i : {1, 2}) {
    EXPECT_EQ(res["episodes"][i]["outcome"], "infrastructure_failure");
    const std::string why = res["episodes"][i]["failure"];
    const std::string rank = i == 1 ? "rank 1 of 2 on " : "rank 0 of 2 on ";
    EXPECT_EQ(why.rfind(rank + host + ": job " + std::to_string(i) + ": crashed with signal 9", 0),
              0u)
        << "episode " << i << ": " << why;
  }
  EXPECT_EQ(res["episodes"][0]["outcome"], "success");
}

TEST_F(MpiJobs, TheReasonOfAnErrorEveryRankMeetsIsPrintedOnceAndNoRankAborts) {
  CD_NEEDS_SUMO();
  // A folder held by another job: rank 0 meets it and tells the others, which end without
  // MPI_Abort (it would race rank 0's line). Five times: a race shows.
  const std::string cfg = test::write_test_config(dir);
  RunLock held = lock_run_folder(dir / "held", "eval");
  for (int k = 0; k < 5; ++k) {
    auto r = mpirun(3, test::eval_args(cfg, "expert", "", "quickstart", dir / "held", 1));
    EXPECT_FALSE(r.exited && r.exit_code == 0) << r.describe();
    const std::string said = " is held by eval (host ";
    ASSERT_NE(r.err.find(said), std::string::npos) << "run " << k << ": " << r.describe();
    EXPECT_EQ(r.err.find(said), r.err.rfind(said)) << r.err;
    EXPECT_NE(r.err.find("rank 0 of 3 on "), std::string::npos) << r.err;
    EXPECT_EQ(r.err.find("MPI_ABORT"), std::string::npos) << "no rank aborts: " << r.err;
  }
}

TEST_F(MpiJobs, MujocoCollectSpreadsTheSameWayAndAHeldFolderStopsEveryRank) {
  CD_NEEDS_MUJOCO();
  const std::vector<std::string> job = {"collect", "--env", "hopper", "--episodes", "3",
                                        "--max-steps", "12"};
  test::run_cli_ok(test::with(job, {"--workers", "2", "--out", dir / "workers"}));
  auto m = mpirun(3, test::with(job, {"--workers", "1", "--out", dir / "mpi"}));
  ASSERT_TRUE(m.exited && m.exit_code == 0) << m.describe();
  const auto a = tree_bytes(dir / "workers");
  EXPECT_EQ(a.size(), 4u);
  EXPECT_TRUE(a == tree_bytes(dir / "mpi")) << "collect --env under mpirun differs";
  // The ranks share one lock: a folder another job holds stops them all, said once.
  RunLock held = lock_run_folder(dir / "mpi", "collect");
  auto r = mpirun(2, test::with(job, {"--workers", "1", "--out", dir / "mpi"}));
  EXPECT_FALSE(r.exited && r.exit_code == 0) << r.describe();
  const std::string said = " is held by collect (host ";
  ASSERT_NE(r.err.find(said), std::string::npos) << r.describe();
  EXPECT_EQ(r.err.find(said), r.err.rfind(said)) << r.err;
  held.release();
  EXPECT_TRUE(a == tree_bytes(dir / "mpi")) << "the refused job wrote into the held folder";
}

TEST_F(MpiJobs, CommandsThatDoNotSpreadAreRefusedInOneLine) {
  auto r = mpirun(2, {"train", "--method", "bc-oh", "--data", dir / "none", "--out", dir / "run"});
  EXPECT_FALSE(r.exited && r.exit_code == 0) << r.describe();
  const std::string refusal = "'train' runs in one process; only collect and eval spread";
  ASSERT_NE(r.err.find(refusal), std::string::npos) << r.describe();
  EXPECT_EQ(r.err.find(refusal), r.err.rfind(refusal)) << "rank 0 alone says it: " << r.err;
  EXPECT_FALSE(fs::exists(dir / "run"));
}

// --- the lock through the CLI -------------------------------------------------------------

TEST(RunLockCli, ASecondEvalIntoAHeldFolderIsRefusedAndTheFirstRunsFilesStay) {
  CD_NEEDS_SUMO();
  TempDir dir("cdtest-lock");
  const std::string cfg = test::write_test_config(dir);
  const std::string out = dir / "out";
  test::run_cli_ok(test::eval_args(cfg, "expert", "", "quickstart", out, 2));
  EXPECT_TRUE(test::lock_released(out)) << "released at the end";
  const auto before = tree_bytes(out);
  // This test process holds the folder as a running eval would (core/run_lock).
  RunLock held = lock_run_folder(out, "eval");
  auto r = test::run_cli(test::eval_args(cfg, "expert", "", "quickstart", out, 2));
  test::expect_one_line_error(r, out + " is held by eval (host ");
  EXPECT_NE(r.err.find("pid " + std::to_string(::getpid()) + ", since "), std::string::npos) << r.err;
  held.release();
  EXPECT_TRUE(tree_bytes(out) == before) << "the refused run touched the first run's files";
}

TEST(RunLockCli, ConcurrentTrainIntoOneFolderIsRefusedNamingTheFirst) {
  CD_NEEDS_SUMO();
  test::TinyRun tiny({.method = "bc-oh", .extra = "\n[train]\nepochs = 2\n"});
  const std::string data = tiny.data(), out = tiny.dir() / "run";
  // The first train is frozen (SIGSTOP) once it holds the folder, so the second meets it.
  // "Holds": its lock file names it (the file exists a moment before its holder line does).
  const pid_t first = test::spawn_group(
      {CD_BINARY, "train", "--config", tiny.config(), "--method", "bc-oh", "--data", data,
       "--out", out}, tiny.dir() / "first.out", tiny.dir() / "first.err");
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  auto holds = [&] {
    return fs::exists(out + "/" + kRunLockName) &&
           test::read_text(out + "/" + kRunLockName).find("state held") != std::string::npos;
  };
  while (!holds() && std::chrono::steady_clock::now() < deadline)
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  ::kill(-first, SIGSTOP);
  ASSERT_TRUE(fs::exists(out + "/" + kRunLockName)) << test::read_text(tiny.dir() / "first.err");
  auto second = test::run_cli(test::train_args(tiny.config(), "bc-oh", data, out));
  ::kill(-first, SIGCONT);
  test::expect_one_line_error(second, out + " is held by train (host ");
  EXPECT_NE(second.err.find("pid " + std::to_string(first) + ","), std::string::npos) << second.err;
  int status = 0;
  ::waitpid(first, &status, 0);
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0)
      << test::read_text(tiny.dir() / "first.err");
  EXPECT_TRUE(fs::exists(out + "/checkpoint.json")) << "the first train finished its run";
}

TEST(RunLockCli, AStaleLockOfADeadProcessIsTakenOverAndSaid) {
  CD_NEEDS_SUMO();
  TempDir dir("cdtest-lock");
  const std::string cfg = test::write_test_config(dir);
  const std::string out = dir / "out";
  fs::create_directories(out);
  test::write_text(out + "/" + kRunLockName,
                   "command eval\nhost elsewhere\npid 999999\nstarted 2026-11-26T05:00:00Z\n");
  auto r = test::run_cli(test::eval_args(cfg, "expert", "", "quickstart", out, 2));
  ASSERT_TRUE(r.exited && r.exit_code == 0) << r.describe();
  EXPECT_NE(r.err.find("taking over the lock of eval (host elsewhere, pid 999999"),
            std::string::npos)
      << r.err;
  EXPECT_TRUE(fs::exists(out + "/results.json"));
  EXPECT_TRUE(test::lock_released(out));
}

}  // namespace
}  // namespace cd
