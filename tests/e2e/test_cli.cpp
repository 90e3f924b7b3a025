// The causaldrive binary: error paths (one line "causaldrive: error: ...", exit code 1),
// --help of every subcommand, `town --list`, `bench world --json`.
#include <gtest/gtest.h>
#include <signal.h>

#include <filesystem>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "../support/fake_episodes.hpp"
#include "../support/test_support.hpp"
#include "core/build_parts.hpp"
#include "device/device.hpp"

namespace cd {
namespace {

using test::CommandResult;
using test::TempDir;

// The contract of every user error: exit code 1 (no signal, no core dump) and exactly one
// line on stderr starting with "causaldrive: error:". Returns that line.
std::string expect_one_line_error(const CommandResult& r, const std::string& what) {
  EXPECT_FALSE(r.timed_out) << what;
  EXPECT_TRUE(r.exited) << what << ": " << r.describe();
  EXPECT_FALSE(r.core_dumped) << what;
  EXPECT_EQ(r.exit_code, 1) << what << ": " << r.describe();
  std::vector<std::string> lines = test::split_lines(r.err);
  EXPECT_EQ(lines.size(), 1u) << what << ": stderr should be one line:\n" << r.err;
  if (lines.empty()) return "";
  EXPECT_TRUE(test::starts_with(lines.front(), "causaldrive: error:"))
      << what << ": " << lines.front();
  return lines.front();
}

bool has(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

TEST(CliErrors, MissingConfigFile) {
  TempDir dir("cdtest-cli");
  CommandResult r =
      test::run_cli({"collect", "--config", "/nonexistent.toml", "--out", dir / "data"});
  std::string line = expect_one_line_error(r, "collect --config /nonexistent.toml");
  EXPECT_TRUE(has(line, "/nonexistent.toml")) << line;
  EXPECT_TRUE(has(line, "not found")) << line;
  EXPECT_FALSE(test::fs::exists(dir / "data")) << "nothing should be written on a config error";
}

TEST(CliErrors, MalformedConfig) {
  TempDir dir("cdtest-cli");
  const std::string config = dir / "bad.toml";
  test::write_text(config, "[world]\ntown = \"town-a\"\ntraffic = = 3\n");
  CommandResult r = test::run_cli({"collect", "--config", config, "--out", dir / "data"});
  std::string line = expect_one_line_error(r, "collect with malformed TOML");
  EXPECT_TRUE(has(line, config)) << line;
  EXPECT_TRUE(has(line, config + ":3") || has(line, "line 3")) << line;
  EXPECT_FALSE(test::fs::exists(dir / "data"));
}

TEST(CliErrors, UnknownConfigKey) {
  TempDir dir("cdtest-cli");
  const std::string config = dir / "unknown.toml";
  test::write_text(config, test::test_config_toml("empty", "\n[collect.noise]\nfoo = 1\n"));
  CommandResult r = test::run_cli({"collect", "--config", config, "--out", dir / "data"});
  std::string line = expect_one_line_error(r, "collect with an unknown key");
  EXPECT_TRUE(has(line, "collect.noise.foo")) << line;
  EXPECT_TRUE(has(line, config)) << line;

  // The same for every subcommand that takes a config.
  r = test::run_cli({"bench", "world", "--config", config, "--steps", "10"});
  line = expect_one_line_error(r, "bench world with an unknown key");
  EXPECT_TRUE(has(line, "collect.noise.foo")) << line;
  r = test::run_cli({"town", "town-a", "--config", config});
  line = expect_one_line_error(r, "town with an unknown key");
  EXPECT_TRUE(has(line, "collect.noise.foo")) << line;
}

TEST(CliErrors, TownPreviewOfMissingNetwork) {
  TempDir dir("cdtest-cli");
  CommandResult r =
      test::run_cli({"town", "--net", "/nonexistent.net.xml", "--preview", dir / "x.png"});
  std::string line = expect_one_line_error(r, "town --net /nonexistent.net.xml");
  EXPECT_TRUE(has(line, "/nonexistent.net.xml")) << line;
  EXPECT_FALSE(test::fs::exists(dir / "x.png"));
}

TEST(CliErrors, TownPreviewOfBrokenNetwork) {
  CD_NEEDS_SUMO();
  TempDir dir("cdtest-cli");
  const std::string net = dir / "BROKEN.net.xml";
  test::write_text(net, "not xml\n");
  CommandResult r = test::run_cli({"town", "--net", net, "--preview", dir / "x.png"});
  std::string line = expect_one_line_error(r, "town --net BROKEN.net.xml");
  EXPECT_TRUE(has(line, "BROKEN.net.xml")) << line;
  EXPECT_FALSE(test::fs::exists(dir / "x.png"));
}

TEST(CliErrors, CollectOnMissingNetwork) {
  CD_NEEDS_SUMO();
  TempDir dir("cdtest-cli");
  const std::string config = test::write_test_config(dir);
  CommandResult r = test::run_cli({"collect", "--config", config, "--town", "/nonexistent.net.xml",
                                   "--out", dir / "data"});
  std::string line = expect_one_line_error(r, "collect --town /nonexistent.net.xml");
  EXPECT_TRUE(has(line, "/nonexistent.net.xml")) << line;
  for (const std::string& name : test::list_dir(dir / "data"))
    EXPECT_FALSE(test::ends_with(name, ".h5")) << name;
}

TEST(CliErrors, UnknownTownName) {
  CommandResult r = test::run_cli({"town", "town-zzz"});
  std::string line = expect_one_line_error(r, "town town-zzz");
  EXPECT_TRUE(has(line, "town-zzz")) << line;
  EXPECT_TRUE(has(line, "town-a")) << "should list the known towns: " << line;
}

TEST(CliHelp, EverySubcommandHasHelp) {
  const std::vector<std::vector<std::string>> commands = {
      {"--help"},          {"quickstart", "--help"}, {"town", "--help"},
      {"collect", "--help"}, {"bench", "--help"},    {"bench", "world", "--help"},
      {"train", "--help"}, {"eval", "--help"},       {"granger", "--help"},
      {"report", "--help"}, {"diagnose", "--help"}};
  for (const auto& args : commands) {
    std::string cmd;
    for (const auto& a : args) cmd += a + " ";
    CommandResult r = test::run_cli(args);
    EXPECT_TRUE(r.exited && r.exit_code == 0) << cmd << ": " << r.describe();
    EXPECT_TRUE(has(r.out, "Usage")) << cmd << ": " << r.out;
    if (args.size() > 1) {
      EXPECT_TRUE(has(r.out, args[args.size() - 2])) << cmd << ": " << r.out;
    }
  }
  CommandResult collect = test::run_cli({"collect", "--help"});
  for (const char* opt : {"--config", "--episodes", "--workers", "--seed", "--out", "--png"})
    EXPECT_TRUE(has(collect.out, opt)) << "collect --help should mention " << opt;
}

// A bad command line (unknown option, bad value, missing subcommand) is one line on stderr
// naming the problem, with exit status 2; --help and --version still succeed.
TEST(CliErrors, BadCommandLinesAreOneLineUsageErrors) {
  const std::vector<std::pair<std::vector<std::string>, std::string>> cases = {
      {{"eval", "--bogus"}, "--bogus"},
      {{"collect", "--episodes", "-3"}, "-3 is not a non-negative number"},
      {{"collect", "--episodes", "x"}, "x is not a non-negative number"},
      {{"eval", "--sensor", "foggy"}, "foggy"},
      {{}, "subcommand"},
  };
  for (const auto& [args, needle] : cases) {
    const CommandResult r = test::run_cli(args);
    EXPECT_TRUE(r.exited && r.exit_code == 2) << r.describe();
    EXPECT_EQ(test::split_lines(r.err).size(), 1u) << r.describe();
    EXPECT_TRUE(has(r.err, needle)) << r.describe();
    EXPECT_TRUE(has(r.err, "causaldrive: error:")) << r.describe();
  }
  const CommandResult v = test::run_cli({"--version"});
  EXPECT_TRUE(v.exited && v.exit_code == 0) << v.describe();
}

// Asking for CUDA where the build or the machine has none: one line naming which, from the
// option and from the config alike, before anything is written. (On a CUDA machine the same
// commands run: scripts/gpu_check.sh.)
TEST(CliDevice, CudaWhereThereIsNoneIsOneLineNamingWhy) {
  if (cuda_usable()) GTEST_SKIP() << "this machine has CUDA";
  TempDir dir("cd-cli-device");
  test::write_fake_folder(dir / "data", 3, {.frames = 30});
  const std::string why = torch_built_with_cuda() ? "this machine has no GPU" : "has no CUDA";
  const std::string out = dir / "run";
  std::string line = expect_one_line_error(
      test::run_cli({"train", "--method", "bc-oh", "--data", dir / "data", "--out", out,
                     "--device", "cuda"}),
      "train --device cuda");
  EXPECT_TRUE(has(line, "train.device = \"cuda\", but ")) << line;
  EXPECT_TRUE(has(line, why)) << line;
  EXPECT_FALSE(std::filesystem::exists(out)) << "a refused run leaves no folder";

  const std::string config = dir / "cuda.toml";
  test::write_text(config, "[train]\ndevice = \"cuda\"\nepochs = 1\n");
  line = expect_one_line_error(
      test::run_cli({"train", "--config", config, "--method", "bc-oh", "--data", dir / "data",
                     "--out", out}),
      "train.device = cuda in the config");
  EXPECT_TRUE(has(line, why)) << line;

  if (built_with_sumo()) {  // driving eval needs the world
    line = expect_one_line_error(
        test::run_cli({"eval", "--agent", "expert", "--suite", "quickstart", "--out",
                       dir / "eval", "--device", "cuda"}),
        "eval --device cuda");
    EXPECT_TRUE(has(line, "eval.device = \"cuda\", but ")) << line;
    EXPECT_FALSE(std::filesystem::exists(dir / "eval"));
  }

  // auto trains on the CPU and says so in the record.
  const test::CommandResult r = test::run_cli({"train", "--method", "bc-oh", "--data",
                                               dir / "data", "--out", out, "--epochs", "1",
                                               "--threads", "1"});
  ASSERT_TRUE(r.exited && r.exit_code == 0) << r.describe();
  const nlohmann::json ck = nlohmann::json::parse(test::read_text(out + "/checkpoint.json"));
  EXPECT_EQ(ck.at("settings").at("train").at("device"), "auto");
  EXPECT_EQ(ck.at("runtime").at("device"), "cpu");

  const test::CommandResult v = test::run_cli({"--version"});
  EXPECT_TRUE(has(v.out, torch_built_with_cuda() ? "CUDA: built in" : "CUDA: not built in"))
      << v.out;
}

TEST(CliTown, ListShowsTheBuiltInTowns) {
  CommandResult r = test::run_cli({"town", "--list"});
  ASSERT_TRUE(r.exited && r.exit_code == 0) << r.describe();
  std::vector<std::string> names;
  for (const std::string& line : test::split_lines(r.out)) {
    std::string first = line.substr(0, line.find_first_of(" \t"));
    if (!first.empty()) names.push_back(first);
  }
  for (const char* town : {"town-a", "town-b", "town-c"})
    EXPECT_NE(std::find(names.begin(), names.end(), town), names.end())
        << town << " missing from:\n" << r.out;
}

TEST(CliTown, PreviewOfABuiltInTownIsAPng) {
  CD_NEEDS_SUMO();
  TempDir dir("cdtest-cli");
  const std::string png = dir / "a.png";
  CommandResult r = test::run_cli({"town", "town-a", "--preview", png});
  ASSERT_TRUE(r.exited && r.exit_code == 0) << r.describe();
  ASSERT_TRUE(test::fs::exists(png)) << r.describe();
  EXPECT_EQ(test::read_text(png).substr(0, 8), "\x89PNG\r\n\x1a\n");
}

TEST(CliBench, WorldJsonHasTheThreeRates) {
  CD_NEEDS_SUMO();
  TempDir dir("cdtest-cli");
  const std::string config = test::write_test_config(dir, "regular");
  CommandResult r = test::run_cli({"bench", "world", "--config", config, "--steps", "300", "--json"});
  ASSERT_TRUE(r.exited && r.exit_code == 0) << r.describe();
  std::vector<std::string> lines = test::split_lines(r.out);
  ASSERT_EQ(lines.size(), 1u) << "stdout should be one JSON object:\n" << r.out;
  nlohmann::json j;
  ASSERT_NO_THROW(j = nlohmann::json::parse(lines.front())) << lines.front();
  ASSERT_TRUE(j.is_object()) << lines.front();
  for (const char* key : {"sumo_steps_per_s", "full_steps_per_s", "ratio", "ratio_min",
                          "ratio_q25", "ratio_q75", "ratio_max", "slices"}) {
    ASSERT_TRUE(j.contains(key)) << key << " missing: " << lines.front();
    ASSERT_TRUE(j[key].is_number()) << key << ": " << lines.front();
    EXPECT_GT(j[key].get<double>(), 0.0) << key;
  }
  // The ratio is the median of the per-slice ratios (6 slices by default): inside their range
  // and quartiles.
  EXPECT_EQ(j["slices"].get<int>(), 6);
  const double ratio = j["ratio"];
  EXPECT_LE(j["ratio_min"].get<double>(), j["ratio_q25"].get<double>());
  EXPECT_LE(j["ratio_q25"].get<double>(), ratio);
  EXPECT_LE(ratio, j["ratio_q75"].get<double>());
  EXPECT_LE(j["ratio_q75"].get<double>(), j["ratio_max"].get<double>());
}

// bench eval --profile: the phases of a step add up to the step (the rest is "other"), each
// non-negative; the agent without a network spends almost nothing in act().
TEST(CliBench, EvalProfileSplitsTheStep) {
  CD_NEEDS_SUMO();
  TempDir dir("cdtest-cli");
  const std::string config = test::write_test_config(dir, "regular");
  CommandResult r = test::run_cli({"bench", "eval", "--config", config, "--agent", "cs",
                                   "--suite", "quickstart", "--episodes", "1", "--profile",
                                   "--json"});
  ASSERT_TRUE(r.exited && r.exit_code == 0) << r.describe();
  const nlohmann::json j = nlohmann::json::parse(r.out);
  for (const char* who : {"agent", "expert"}) {
    const nlohmann::json& p = j["profile"][who];
    double sum = 0;
    for (const char* phase : {"sense_us", "act_us", "world_us", "score_us", "other_us"}) {
      EXPECT_GE(p[phase].get<double>(), -1e-6) << who << " " << phase;
      sum += p[phase].get<double>();
    }
    EXPECT_NEAR(sum, p["step_us"].get<double>(), 1e-6 * p["step_us"].get<double>()) << who;
    EXPECT_GT(p["world_us"].get<double>(), 0) << who;
  }
  EXPECT_LT(j["profile"]["agent"]["act_us"].get<double>(),
            j["profile"]["agent"]["world_us"].get<double>());
}

TEST(CliBench, WorldSlicesAreAnOption) {
  CD_NEEDS_SUMO();
  TempDir dir("cdtest-cli");
  const std::string config = test::write_test_config(dir, "empty");
  CommandResult r = test::run_cli(
      {"bench", "world", "--config", config, "--steps", "40", "--slices", "2", "--json"});
  ASSERT_TRUE(r.exited && r.exit_code == 0) << r.describe();
  const nlohmann::json j = nlohmann::json::parse(test::split_lines(r.out).front());
  EXPECT_EQ(j["slices"].get<int>(), 2);
  // With two slices the median is the mean of the two ratios: between min and max.
  EXPECT_NEAR(j["ratio"].get<double>(),
              0.5 * (j["ratio_min"].get<double>() + j["ratio_max"].get<double>()), 1e-9);
}

}  // namespace
}  // namespace cd
