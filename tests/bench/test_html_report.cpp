// The HTML report's pieces against hand computation: base64 (RFC 4648's test vectors), the
// failure's step of a recorded episode, the default choice of replays, and the page's tables
// as `report`'s Markdown row for row.
#include "bench/html_report.hpp"

#include <gtest/gtest.h>

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "../support/test_support.hpp"

namespace cd {
namespace {

using test::TempDir;

TEST(HtmlReport, Base64MatchesRfc4648) {
  const std::vector<std::pair<std::string, std::string>> vectors = {
      {"", ""},          {"f", "Zg=="},         {"fo", "Zm8="},         {"foo", "Zm9v"},
      {"foob", "Zm9vYg=="}, {"fooba", "Zm9vYmE="}, {"foobar", "Zm9vYmFy"}};
  for (const auto& [in, out] : vectors) EXPECT_EQ(base64(in), out) << in;
  EXPECT_EQ(base64(std::string("\xff\x00\x10", 3)), "/wAQ");
}

TEST(HtmlReport, TheFailuresStepIsTheCollisionOrTheStartOfTheLastFreeStandstill) {
  // speed:     moving, stands (blocked), moves, stands with a free path to the end.
  const std::vector<float> speed = {3, 2, 0.1f, 0.2f, 1.5f, 0.4f, 0.0f, 0.0f, 0.0f};
  const std::vector<float> path_free = {1, 1, 0, 0, 1, 0, 1, 1, 1};
  EXPECT_EQ(failure_step("collision", speed, path_free), 8);
  EXPECT_EQ(failure_step("offroad", speed, path_free), 8);
  // Step 5 stands but is blocked: the free standstill starts at 6.
  EXPECT_EQ(failure_step("inertia", speed, path_free), 6);
  EXPECT_EQ(failure_step("success", speed, path_free), -1);
  EXPECT_EQ(failure_step("timeout", speed, path_free), -1);
  EXPECT_EQ(failure_step("collision", {}, {}), -1);
}

TEST(HtmlReport, ReplaysTheFirstFailureOfEachKindOrTheEpisodesAsked) {
  TempDir dir("cdtest-html");
  nlohmann::json res = {{"agent", "bc-so"}, {"suite", "town-a-regular"}, {"summary", {}},
                        {"episodes", nlohmann::json::array()}};
  for (const char* o : {"success", "inertia", "collision", "inertia", "timeout", "collision"})
    res["episodes"].push_back({{"outcome", o}});
  RunResult run;
  run.path = dir / "results.json";
  run.label = "bc-so";
  test::write_text(run.path, res.dump());
  const std::vector<RunResult> runs = {run};
  std::vector<ReplayPick> picks = pick_replays(runs, {});
  ASSERT_EQ(picks.size(), 2u);
  EXPECT_EQ(picks[0].episode, 2);
  EXPECT_EQ(picks[0].outcome, "collision");
  EXPECT_EQ(picks[1].episode, 1);
  EXPECT_EQ(picks[1].outcome, "inertia");
  HtmlReportOptions o;
  o.episodes = {4, 0, 99};  // 99 is not an episode of this run
  picks = pick_replays(runs, o);
  ASSERT_EQ(picks.size(), 2u);
  EXPECT_EQ(picks[0].episode, 4);
  EXPECT_EQ(picks[1].outcome, "success");
  o.max_replays = 1;
  EXPECT_EQ(pick_replays(runs, o).size(), 1u);
}

}  // namespace
}  // namespace cd
