// The main job end to end on a tiny config: collect, train bc-oh and cim, evaluate four agents,
// print the table, and resume everything when run again.
// needs: sumo
#include <gtest/gtest.h>

#include <filesystem>

#include "../support/tiny_run.hpp"

namespace cd {
namespace {

namespace fs = std::filesystem;
using test::TempDir;

TEST(Quickstart, RunsTheWholeChainAndResumes) {
  TempDir dir("cdtest-quickstart");
  const std::string suite = test::write_suite({.seed = 5}, dir / "one.json");  // a leader task
  const std::string cfg = test::write_test_config(
      dir, "regular",
      "\n[train]\nepochs = 1\nthreads = 1\nout = \"" + (dir / "train") + "\"\n" +
          "\n[vae]\nlatents = 16\nepochs = 1\nmax_frames = 300\n" +
          "\n[cim]\nepochs = 1\nmax_causes = 2\n" + "\n[eval]\nsuite = \"" + suite +
          "\"\nworkers = 1\nout = \"" + (dir / "eval") + "\"\n");
  auto r = test::run_cli({"quickstart", "--config", cfg, "--out", dir / "data"});
  ASSERT_EQ(r.exit_code, 0) << r.describe();
  for (const char* agent : {"expert", "cs", "bc-oh", "cim"}) {
    SCOPED_TRACE(agent);
    EXPECT_NE(r.out.find(std::string("| ") + agent + " "), std::string::npos) << r.out;
    EXPECT_TRUE(fs::exists(dir / ("eval/" + std::string(agent) + "/results.json")));
  }
  EXPECT_TRUE(fs::exists(dir / "train/cim/causes.json"));
  EXPECT_TRUE(fs::exists(dir / "train/bc-oh/best.pt"));
  EXPECT_EQ(test::list_dir(dir / "data").size(), 4u)
      << "2 episodes, collect.json and the released lock";
  // The page beside the evaluations, its path printed; every evaluated episode recorded.
  EXPECT_NE(r.out.find("report: " + (dir / "report.html")), std::string::npos) << r.out;
  const std::string page = test::read_text(dir / "report.html");
  EXPECT_NE(page.find("<table class=\"metrics\">"), std::string::npos);
  EXPECT_NE(page.find("<h2 id=\"replays\">"), std::string::npos);
  EXPECT_TRUE(fs::exists(dir / "eval/cs/episodes/episode_000000.h5"));

  // A second run finds everything done and prints the same table.
  const std::string before = test::read_text(dir / "eval/cim/results.json");
  auto again = test::run_cli({"quickstart", "--config", cfg, "--out", dir / "data"});
  ASSERT_EQ(again.exit_code, 0) << again.describe();
  EXPECT_EQ(test::read_text(dir / "eval/cim/results.json"), before);
  EXPECT_NE(again.out.find("nothing left to train"), std::string::npos) << again.out;
}

}  // namespace
}  // namespace cd
