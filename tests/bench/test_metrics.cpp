// Episode classification and stop-and-go events (SPEC section 5) on hand-made traces.
#include "bench/metrics.hpp"

#include <gtest/gtest.h>

#include <cmath>

#include <nlohmann/json.hpp>

#include "core/error.hpp"
#include "world/ground_truth.hpp"

namespace cd {
namespace {

constexpr double kDt = 0.1;

TEST(BenchMetrics, TimeoutIsRouteAtFiveKmhPlusTwentySeconds) {
  EXPECT_DOUBLE_EQ(route_timeout_s(0), 20.0);
  EXPECT_NEAR(route_timeout_s(300), 300 / (5 / 3.6) + 20, 1e-9);
  EXPECT_NEAR(route_timeout_s(500), 380.0, 1e-9);
}

TEST(BenchMetrics, InertiaNeedsTheLastFifteenSecondsStoppedWithAFreePath) {
  const size_t n15 = 150;  // 15 s at 10 Hz
  std::vector<char> stopped(400, 0), free_path(400, 1);
  for (size_t i = 400 - n15; i < 400; ++i) stopped[i] = 1;
  EXPECT_TRUE(is_inertia(stopped, free_path, kDt));
  // One step less than 15 s stopped: not inertia.
  stopped[400 - n15] = 0;
  EXPECT_FALSE(is_inertia(stopped, free_path, kDt));
  stopped[400 - n15] = 1;
  // Blocked once within the span (the leader stood there): not inertia.
  free_path[390] = 0;
  EXPECT_FALSE(is_inertia(stopped, free_path, kDt));
  // Blocked before the span only: inertia again.
  free_path[390] = 1;
  free_path[100] = 0;
  EXPECT_TRUE(is_inertia(stopped, free_path, kDt));
  // An episode shorter than 15 s cannot show inertia.
  EXPECT_FALSE(is_inertia(std::vector<char>(100, 1), std::vector<char>(100, 1), kDt));
}

// Feeds (speed, free) pairs for `seconds` seconds.
void feed(StopGoTracker& t, double speed, bool free_path, double seconds) {
  for (int i = 0; i < static_cast<int>(std::lround(seconds / kDt)); ++i) t.observe(speed, free_path);
}

// A hand-made episode for the taxonomy: segments of (speed, path free, seconds), fed to the
// tracker as the runner does; classify_timeout on what it saw.
struct Segment {
  double speed;
  bool free;
  double seconds;
};
std::string timeout_class_of(const std::vector<Segment>& segments, bool* paper = nullptr) {
  StopGoTracker t(kDt);
  std::vector<char> stopped, free_path;
  for (const Segment& s : segments)
    for (int i = 0; i < static_cast<int>(std::lround(s.seconds / kDt)); ++i) {
      t.observe(s.speed, s.free);
      stopped.push_back(s.speed < kStoppedSpeed);
      free_path.push_back(s.free);
    }
  t.finish();
  if (paper) *paper = is_paper_inertia(stopped, kDt);
  return classify_timeout(stopped, free_path, t.events(), kDt);
}

TEST(BenchMetrics, TaxonomyPutsEachTimeoutInItsClass) {
  bool paper = false;
  // Driving, stopped on a free road for the last 20 s: stuck (the SPEC's inertia); seed 000's
  // inertia too.
  EXPECT_EQ(timeout_class_of({{8, true, 30}, {0, true, 20}}, &paper), "stuck");
  EXPECT_TRUE(paper);
  // At a red light, green for 8 s while it stood, red again for the last 12 s: it never
  // restarted after the path freed. Not stuck (the last 15 s were not all free).
  EXPECT_EQ(timeout_class_of({{8, true, 30}, {0, false, 10}, {0, true, 8}, {0, false, 12}},
                             &paper),
            "restart_stall");
  EXPECT_TRUE(paper) << "seed 000's rule ignores the path";
  // It stopped on a free road (a spontaneous stop: no event opens), then a light ahead turned
  // red within its reach for the last 10 s.
  EXPECT_EQ(timeout_class_of({{8, true, 30}, {0, true, 7}, {0, false, 10}}), "stopped_free");
  // It stopped behind a leader that never moved on: blocked, however long.
  EXPECT_EQ(timeout_class_of({{8, true, 30}, {0, false, 40}}, &paper), "blocked");
  EXPECT_TRUE(paper);
  // Freed for 3 s, blocked again before it should have gone (the event is dropped): blocked.
  EXPECT_EQ(timeout_class_of({{8, true, 30}, {0, false, 10}, {0, true, 3}, {0, false, 10}}),
            "blocked");
  // Still moving at the end, too slowly: slow; not seed 000's inertia.
  EXPECT_EQ(timeout_class_of({{8, true, 30}, {0, false, 10}, {1.0, true, 30}}, &paper), "slow");
  EXPECT_FALSE(paper);
  // A held start on a free path the agent never left: the start event never started.
  EXPECT_EQ(timeout_class_of({{0, true, 4}, {0, false, 20}}), "blocked")
      << "freed for 4 s only at the start, then blocked: it was right to wait";
  EXPECT_EQ(timeout_class_of({{0, true, 8}, {0, false, 20}}), "restart_stall");
  for (const std::string& c : timeout_classes())
    EXPECT_EQ(is_copycat_class(c), c == "stuck" || c == "restart_stall" || c == "stopped_free")
        << c;
}

TEST(BenchMetrics, TheClassesSumToOneAndCopycatIsThreeOfThem) {
  std::vector<EpisodeResult> eps;
  for (const char* o : {"success", "success", "collision", "stuck", "restart_stall",
                        "restart_stall", "stopped_free", "blocked", "slow", "offroad"}) {
    EpisodeResult e;
    e.outcome = o;
    e.paper_inertia = std::string(o) == "stuck" || std::string(o) == "blocked";
    if (std::string(o) == "collision") e.collision_kind = "vehicle";
    eps.push_back(e);
  }
  const nlohmann::json s = summarize(eps);
  double sum = 0;
  for (const char* k : {"success_rate", "collision_rate", "offroad_rate", "stuck_rate",
                        "restart_stall_rate", "stopped_free_rate", "blocked_rate", "slow_rate"})
    sum += s.at(k).get<double>();
  EXPECT_DOUBLE_EQ(sum, 1.0);
  EXPECT_DOUBLE_EQ(s["copycat_rate"].get<double>(), 0.4);
  EXPECT_DOUBLE_EQ(s["restart_stall_rate"].get<double>(), 0.2);
  EXPECT_DOUBLE_EQ(s["inertia_rate"].get<double>(), 0.1) << "the SPEC's inertia is stuck";
  EXPECT_DOUBLE_EQ(s["timeout_rate"].get<double>(), 0.5) << "every other class";
  EXPECT_DOUBLE_EQ(s["time_limit_rate"].get<double>(), 0.6);
  EXPECT_DOUBLE_EQ(s["error_rate"].get<double>(), 0.2);
  EXPECT_DOUBLE_EQ(s["paper_inertia_rate"].get<double>(), 0.2);
  EXPECT_DOUBLE_EQ(s["paper_error_rate"].get<double>(), 0.3) << "paper inertia + vehicle hits";
}

TEST(BenchMetrics, ARecordWithoutTheTaxonomyIsKnownAsOld) {
  EpisodeResult e;
  e.outcome = "blocked";
  e.last_stop_s = 12.5;
  e.last_stop_cause = "leader";
  e.final_max_speed = {0.1, 0.0};
  e.paper_inertia = true;
  nlohmann::json j = episode_to_json(e);
  const EpisodeResult back = episode_from_json(j);
  EXPECT_TRUE(back.has_taxonomy);
  EXPECT_EQ(back.last_stop_cause, "leader");
  EXPECT_DOUBLE_EQ(*back.last_stop_s, 12.5);
  EXPECT_FALSE(back.last_free_change_s.has_value());
  EXPECT_EQ(back.final_max_speed, (std::vector<double>{0.1, 0.0}));
  EXPECT_TRUE(back.paper_inertia);
  j.erase("taxonomy");
  j["outcome"] = "inertia";
  EXPECT_FALSE(episode_from_json(j).has_taxonomy);
}

TEST(BenchMetrics, StopGoEventTimesTheStartAfterThePathFrees) {
  StopGoTracker t(kDt);
  feed(t, 0.0, false, 3.0);  // waiting at a red light
  feed(t, 0.0, true, 2.0);   // green: the ego still stands 2 s
  feed(t, 3.0, true, 1.0);   // and goes
  t.finish();
  ASSERT_EQ(t.events().size(), 1u);
  const StopGoEvent& e = t.events()[0];
  EXPECT_EQ(e.kind, "freed");
  EXPECT_NEAR(e.time_s, 3.1, 1e-9);   // first step with the path free
  EXPECT_NEAR(e.delay_s, 2.0, 1e-9);  // until the first step above 0.5 m/s
  EXPECT_TRUE(e.started);
  EXPECT_FALSE(e.stall);
}

TEST(BenchMetrics, StallWhenTheDelayExceedsFiveSecondsOrTheEgoNeverStarts) {
  StopGoTracker late(kDt);
  feed(late, 0.0, false, 1.0);
  feed(late, 0.2, true, 6.0);  // creeping below 0.5 m/s is still standing
  feed(late, 1.0, true, 1.0);
  late.finish();
  ASSERT_EQ(late.events().size(), 1u);
  EXPECT_TRUE(late.events()[0].stall);
  EXPECT_TRUE(late.events()[0].started);
  EXPECT_NEAR(late.events()[0].delay_s, 6.0, 1e-9);

  StopGoTracker never(kDt);
  feed(never, 0.0, false, 1.0);
  feed(never, 0.0, true, 20.0);
  never.finish();
  ASSERT_EQ(never.events().size(), 1u);
  EXPECT_TRUE(never.events()[0].stall);
  EXPECT_FALSE(never.events()[0].started);
  EXPECT_NEAR(never.events()[0].delay_s, 19.9, 1e-9);  // censored at the episode's end
}

TEST(BenchMetrics, BlockedAgainBeforeTheStallTimeIsNoEvent) {
  StopGoTracker t(kDt);
  feed(t, 0.0, false, 1.0);
  feed(t, 0.0, true, 2.0);   // freed, but before the ego goes ...
  feed(t, 0.0, false, 3.0);  // ... blocked again: it was right to wait
  feed(t, 0.0, true, 1.0);   // freed again: a new event
  feed(t, 2.0, true, 1.0);
  t.finish();
  ASSERT_EQ(t.events().size(), 1u);
  EXPECT_NEAR(t.events()[0].time_s, 6.1, 1e-9);
  EXPECT_NEAR(t.events()[0].delay_s, 1.0, 1e-9);
}

TEST(BenchMetrics, FreePathAtTakeoverIsAStartEventAndMovingEgoMakesNone) {
  StopGoTracker t(kDt);
  feed(t, 0.0, true, 0.5);
  feed(t, 5.0, true, 3.0);
  feed(t, 5.0, false, 1.0);  // the path blocks and frees while the ego drives: no event
  feed(t, 5.0, true, 1.0);
  t.finish();
  ASSERT_EQ(t.events().size(), 1u);
  EXPECT_EQ(t.events()[0].kind, "start");
  EXPECT_NEAR(t.events()[0].delay_s, 0.5, 1e-9);
}

TEST(BenchMetrics, SummaryRatesExcludeInfrastructureFailures) {
  std::vector<EpisodeResult> eps(5);
  const char* outcomes[] = {"success", "collision", "inertia", "timeout",
                            "infrastructure_failure"};
  for (int i = 0; i < 5; ++i) {
    eps[i].outcome = outcomes[i];
    eps[i].route_length_m = 400;
    eps[i].distance_m = 200;
    eps[i].duration_s = 100;
  }
  eps[0].distance_m = 400;
  eps[0].red_light_violations = 1;
  eps[1].events = {{1.0, 1.0, true, false, "start"}, {5.0, 7.0, true, true, "freed"}};
  eps[2].events = {{1.0, 3.0, true, false, "start"}};
  nlohmann::json s = summarize(eps);
  EXPECT_EQ(s["episodes"], 4);
  EXPECT_EQ(s["infrastructure_failures"], 1);
  EXPECT_DOUBLE_EQ(s["success_rate"].get<double>(), 0.25);
  EXPECT_DOUBLE_EQ(s["collision_rate"].get<double>(), 0.25);
  EXPECT_DOUBLE_EQ(s["inertia_rate"].get<double>(), 0.25);
  EXPECT_DOUBLE_EQ(s["timeout_rate"].get<double>(), 0.25);
  EXPECT_DOUBLE_EQ(s["time_limit_rate"].get<double>(),
                   s["timeout_rate"].get<double>() + s["inertia_rate"].get<double>());
  EXPECT_DOUBLE_EQ(s["error_rate"].get<double>(), 0.5);
  EXPECT_EQ(s["stop_go_events"], 3);
  EXPECT_EQ(s["stalls"], 1);
  EXPECT_NEAR(s["stall_rate"].get<double>(), 1.0 / 3, 1e-12);
  EXPECT_DOUBLE_EQ(s["start_delay_median_s"].get<double>(), 3.0);
  EXPECT_NEAR(s["start_delay_p90_s"].get<double>(), 3.0 + 0.8 * 4.0, 1e-12);
  // 1 violation over 1.0 km driven (400 + 3 x 200 m).
  EXPECT_NEAR(s["red_light_violations_per_km"].get<double>(), 1.0, 1e-12);
  EXPECT_NEAR(s["route_completion"].get<double>(), (1 + 0.5 * 3) / 4, 1e-12);
  EXPECT_NEAR(s["mean_speed"].get<double>(), 1000.0 / 400.0, 1e-12);
  // No events at all: the delays are null, not zero.
  nlohmann::json none = summarize({eps[3]});
  EXPECT_TRUE(none["start_delay_median_s"].is_null());
}

TEST(BenchMetrics, CollisionKindsAndThePapersError) {
  // 8 episodes: inertia x2, a vehicle the ego struck, a vehicle that struck the ego, a
  // pedestrian the ego struck, a collision recorded before kinds existed, success, timeout.
  std::vector<EpisodeResult> eps(8);
  const char* outcomes[] = {"inertia", "inertia", "collision", "collision",
                            "collision", "collision", "success", "timeout"};
  for (int i = 0; i < 8; ++i) eps[i].outcome = outcomes[i];
  eps[0].paper_inertia = eps[1].paper_inertia = true;  // stood the last 15 s
  eps[2].collision_kind = "vehicle", eps[2].collision_by = "ego";
  eps[3].collision_kind = "vehicle", eps[3].collision_by = "other";
  eps[4].collision_kind = "pedestrian", eps[4].collision_by = "ego";
  nlohmann::json s = summarize(eps);
  EXPECT_DOUBLE_EQ(s["collision_rate"].get<double>(), 4.0 / 8);
  EXPECT_DOUBLE_EQ(s["vehicle_collision_rate"].get<double>(), 2.0 / 8);
  EXPECT_DOUBLE_EQ(s["pedestrian_collision_rate"].get<double>(), 1.0 / 8);
  EXPECT_DOUBLE_EQ(s["ego_struck_collision_rate"].get<double>(), 2.0 / 8);
  EXPECT_DOUBLE_EQ(s["error_rate"].get<double>(), 6.0 / 8);
  // Seed 000's error: its inertia + collisions with cars (pedestrians and unknown kinds out).
  EXPECT_DOUBLE_EQ(s["paper_error_rate"].get<double>(), 4.0 / 8);
  EpisodeResult back = episode_from_json(episode_to_json(eps[4]));
  EXPECT_EQ(back.collision_kind, "pedestrian");
  EXPECT_EQ(back.collision_by, "ego");
  EXPECT_FALSE(episode_to_json(eps[6]).contains("collision_kind"));
}

TEST(BenchMetrics, EpisodeRecordRoundTrip) {
  EpisodeResult e;
  e.index = 7;
  e.task = 2;
  e.trial = 1;
  e.scenario = "leader";
  e.traffic_seed = 123456789012345ULL;
  e.outcome = "collision";
  e.collided_with = "bg4";
  e.route_length_m = 321.5;
  e.distance_m = 100.25;
  e.duration_s = 30;
  e.red_light_violations = 2;
  e.light_passages = 5;
  e.green_light_entries = 3;
  e.events = {{4.5, 1.2, true, false, "freed"}};
  EpisodeResult back = episode_from_json(episode_to_json(e));
  EXPECT_EQ(episode_to_json(back).dump(), episode_to_json(e).dump());
  EXPECT_EQ(back.light_passages, 5);
  EXPECT_EQ(back.green_light_entries, 3);
  EXPECT_THROW(episode_from_json(nlohmann::json{{"index", 1}}), DataError);
  // A record written before the light counts existed is run again, not read as zero passages.
  nlohmann::json old = episode_to_json(e);
  old.erase("light_passages");
  EXPECT_THROW(episode_from_json(old), DataError);
}

// One step of a hand-made drive: the lane before and after it and the first signalised link
// of the path before it (SUMO state character, distance).
struct DriveStep {
  const char* prev_lane;
  const char* lane;
  char light;
  double light_distance;
};

// Runs the steps through the world's detection and the episode's count, as run_episode does.
EpisodeResult drive(const std::vector<DriveStep>& steps) {
  EpisodeResult r;
  for (const DriveStep& s : steps)
    count_junction_entry(r, light_at_junction_entry(s.prev_lane, s.lane, s.light, s.light_distance));
  return r;
}

TEST(BenchMetrics, GreenLightRateCountsLightControlledEntriesOnly) {
  EpisodeResult r = drive({
      {"e1_0", "e1_0", 'r', 3.0},         // waiting at a red light: no entry
      {"e1_0", ":j1_0_0", 'r', 1.0},      // entered on red: a passage and a violation
      {":j1_0_0", ":j1_0_1", 'G', 0.0},   // inside the junction: no new entry
      {":j1_0_1", "e2_0", 'G', 1e9},      // leaving it
      {"e2_0", ":j2_3_0", 'G', 2.0},      // entered on green
      {":j2_3_0", "e3_0", 0, 1e9},
      {"e3_0", ":j3_1_0", 0, 1e9},        // an unsignalised junction: no light ahead
      {":j3_1_0", "e4_0", 0, 1e9},
      {"e4_0", ":j4_0_0", 'G', 40.0},     // unsignalised, the next light 40 m further on
      {":j4_0_0", "e5_0", 'G', 30.0},
      {"e5_0", ":j5_2_0", 'g', 1.5},      // green without priority is green
      {":j5_2_0", "e6_0", 0, 1e9},
      {"e6_0", ":j6_0_0", 'y', 0.5},      // yellow: a passage, neither green nor a violation
      {":j6_0_0", ":j6_0_1", 'O', 1e9},
  });
  EXPECT_EQ(r.light_passages, 4);
  EXPECT_EQ(r.green_light_entries, 2);
  EXPECT_EQ(r.red_light_violations, 1);
  EXPECT_EQ(light_at_junction_entry("e1_0", ":j1_0_0", 'r', kLightEntryReach), kTlNone)
      << "a light kLightEntryReach m away is not the junction being entered";
  EXPECT_EQ(light_at_junction_entry("e1_0", ":j1_0_0", 'O', 1.0), kTlNone) << "light off";
}

TEST(BenchMetrics, SummaryPoolsGreenLightPassagesOverEpisodes) {
  std::vector<EpisodeResult> eps(4);
  for (EpisodeResult& e : eps) {
    e.outcome = "success";
    e.route_length_m = e.distance_m = 400;
    e.duration_s = 60;
  }
  eps[0] = drive({{"a", ":j_0", 'r', 1.0}, {":j_0", "b", 0, 1e9}, {"b", ":k_0", 'G', 1.0}});
  eps[0].outcome = "success";
  eps[1].light_passages = 3;  // 3 of 3 on green
  eps[1].green_light_entries = 3;
  // eps[2] passed no light; eps[3] failed for the infrastructure and is left out.
  eps[3].outcome = "infrastructure_failure";
  eps[3].light_passages = 10;
  nlohmann::json s = summarize(eps);
  EXPECT_EQ(s["light_passages"], 5);
  EXPECT_EQ(s["green_light_entries"], 4);
  // Pooled: 4 / 5, not the mean of the episodes' rates ((0.5 + 1) / 2 = 0.75).
  EXPECT_DOUBLE_EQ(s["green_light_rate"].get<double>(), 0.8);
  nlohmann::json none = summarize({eps[2]});
  EXPECT_EQ(none["light_passages"], 0);
  EXPECT_TRUE(none["green_light_rate"].is_null()) << "no passage: no rate, not 0 or 1";
}

}  // namespace
}  // namespace cd
