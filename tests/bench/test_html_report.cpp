// The HTML report's pieces against hand computation: base64 (RFC 4648's test vectors), the
// failure's step of a recorded episode, the default choice of replays, and the page's tables
// as `report`'s Markdown row for row.
#include "bench/html_report.hpp"
#include "bench/report.hpp"

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
  EXPECT_EQ(failure_step("stuck", speed, path_free), failure_step("inertia", speed, path_free));
  EXPECT_EQ(failure_step("slow", speed, path_free), -1);
  // The other standing classes mark the whole final standstill, the path aside: from step 5.
  EXPECT_EQ(failure_step("restart_stall", speed, path_free), 5);
  EXPECT_EQ(failure_step("blocked", speed, path_free), 5);
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

TEST(HtmlReport, AChartKeepsALongLabelWholeAndItsMarkupClosed) {
  // The SVG was formatted into a 512-byte buffer: a bar whose label fills it lost its closing
  // tags, and the page's markup with them.
  TempDir dir("cdtest-html");
  const std::string label(700, 'x');
  nlohmann::json res = {{"agent", "bc-oh"},
                        {"label", label},
                        {"suite", "town-a-regular"},
                        {"summary", {{"success_rate", 0.5}, {"collision_rate", 0.25},
                                     {"copycat_rate", 0.0}, {"episodes", 4}}},
                        {"episodes", nlohmann::json::array()}};
  const std::string path = dir / "results.json";
  test::write_text(path, res.dump());
  const std::vector<RunResult> runs = {load_result(path)};
  HtmlReportOptions o;
  o.max_replays = 0;
  const std::string page = render_html_report(runs, "", o);
  size_t bars = 0, closed = 0;
  for (size_t at = page.find("<rect x="); at != std::string::npos; at = page.find("<rect x=", at + 1))
    if (page.find("data-series=", at) < page.find('>', at)) ++bars;
  for (size_t at = page.find("</rect>"); at != std::string::npos; at = page.find("</rect>", at + 1))
    ++closed;
  EXPECT_EQ(bars, 3u) << "success, collision and copycat";
  EXPECT_EQ(closed, bars) << "every bar is closed";
  EXPECT_NE(page.find("data-label=\"" + label + "\""), std::string::npos) << "the label whole";
  EXPECT_NE(page.find("<title>" + label + ", success: 50.0%"), std::string::npos);
  EXPECT_NE(page.find("</svg></figure>"), std::string::npos);
}

TEST(HtmlReport, ChartWhiskersAreTheRatesIntervalWhereTheRunsListTheirEpisodes) {
  TempDir dir("cdtest-html");
  std::vector<RunResult> runs;
  for (int seed = 0; seed < 2; ++seed) {
    nlohmann::json eps = nlohmann::json::array();
    for (int t = 0; t < 4; ++t)
      eps.push_back({{"task", t}, {"outcome", t < 2 + seed ? "success" : "collision"}});
    const double success = (2.0 + seed) / 4;
    nlohmann::json res = {{"agent", "bc-oh"},
                          {"suite", "town-a-regular"},
                          {"summary", {{"episodes", 4}, {"success_rate", success},
                                       {"collision_rate", 1 - success}, {"copycat_rate", 0.0}}},
                          {"episodes", eps}};
    const std::string path = dir / ("r" + std::to_string(seed) + ".json");
    test::write_text(path, res.dump());
    runs.push_back(load_result(path));
  }
  HtmlReportOptions o;
  o.max_replays = 0;
  const std::string page = render_html_report(runs, "", o);
  const Interval want = *build_report(runs).stats("bc-oh", "town-a-regular", "success_rate")->interval;
  char title[64];
  std::snprintf(title, sizeof title, "success: 62.5%% (95%% [%.1f, %.1f], n 2)", 100 * want.lo,
                100 * want.hi);
  EXPECT_NE(page.find(title), std::string::npos) << title;
  EXPECT_NE(page.find("class=\"ci\""), std::string::npos);
}

}  // namespace
}  // namespace cd
