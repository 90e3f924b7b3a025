// `causaldrive collect --env`: the MuJoCo-Image domain from the command line (one tiny run),
// its one-line errors, and the driving options it refuses.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "../support/test_support.hpp"

namespace cd {
namespace {

using test::CommandResult;
using test::TempDir;

std::string one_line_error(const CommandResult& r, const std::string& what) {
  EXPECT_TRUE(r.exited) << what << ": " << r.describe();
  EXPECT_EQ(r.exit_code, 1) << what << ": " << r.describe();
  const std::vector<std::string> lines = test::split_lines(r.err);
  EXPECT_EQ(lines.size(), 1u) << what << ": stderr should be one line:\n" << r.err;
  return lines.empty() ? "" : lines.front();
}

bool has(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

TEST(CliMujoco, UnknownEnvIsOneLine) {
  TempDir dir("cdtest-mjcli");
  const std::string line = one_line_error(
      test::run_cli({"collect", "--env", "cheetah", "--out", dir / "data"}), "unknown env");
  EXPECT_TRUE(has(line, "unknown MuJoCo environment 'cheetah'")) << line;
  EXPECT_FALSE(test::fs::exists(dir / "data"));
}

TEST(CliMujoco, MissingModelFileIsOneLine) {
  TempDir dir("cdtest-mjcli");
  test::ScopedEnv assets("CAUSALDRIVE_MUJOCO_ASSETS", dir / "nowhere");
  const std::string line = one_line_error(
      test::run_cli({"collect", "--env", "hopper", "--out", dir / "data"}), "missing model");
  EXPECT_TRUE(has(line, dir / "nowhere/hopper.xml")) << line;
}

TEST(CliMujoco, DrivingOptionsAreRefusedWithEnv) {
  TempDir dir("cdtest-mjcli");
  const std::string line = one_line_error(
      test::run_cli({"collect", "--env", "hopper", "--town", "town-a", "--out", dir / "data"}),
      "--town with --env");
  EXPECT_TRUE(has(line, "--town")) << line;
}

TEST(CliMujoco, CollectsATinyDatasetAndResumes) {
  TempDir dir("cdtest-mjcli");
  const std::vector<std::string> args = {"collect", "--env", "reacher", "--episodes", "1",
                                         "--max-steps", "3", "--planner-samples", "4",
                                         "--planner-horizon", "2", "--workers", "1", "--out",
                                         dir / "data"};
  CommandResult r = test::run_cli(args);
  ASSERT_EQ(r.exit_code, 0) << r.describe();
  EXPECT_TRUE(test::fs::exists(dir / "data/episode_000000.h5"));
  EXPECT_TRUE(has(r.out, "recorded now: 1")) << r.out;
  r = test::run_cli(args);
  ASSERT_EQ(r.exit_code, 0) << r.describe();
  EXPECT_TRUE(has(r.out, "recorded now: 0")) << r.out;
}

}  // namespace
}  // namespace cd
