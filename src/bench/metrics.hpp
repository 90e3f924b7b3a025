#pragma once
// The benchmark's episode classification and stop-and-go events (SPEC section 5), as pure
// functions of what happened at each step, so they can be checked on hand-made traces.
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace cd {

inline constexpr double kStoppedSpeed = 0.5;  // m/s: below it the ego is stopped
inline constexpr double kInertiaSpan = 15.0;  // s stopped with a free path before a timeout
inline constexpr double kStallDelay = 5.0;    // s: a longer start delay is a stall

// Timeout of a route: its length at 5 km/h plus 20 s.
double route_timeout_s(double route_length_m);

// Inertia: a timed-out episode whose ego spent at least the last kInertiaSpan seconds below
// kStoppedSpeed with a free path at every one of those steps. `stopped` and `path_free` are
// per step, dt apart, the last entries being the end of the episode.
bool is_inertia(const std::vector<char>& stopped, const std::vector<char>& path_free, double dt);

// Seed 000's inertia: the ego stood (below kStoppedSpeed) the whole last kInertiaSpan
// seconds, whatever its path did.
bool is_paper_inertia(const std::vector<char>& stopped, double dt);

struct StopGoEvent;

// The class of an episode that ran out of time (SPEC section 14), decided in this order:
// "stuck" (is_inertia), "slow" (moving at the end), "restart_stall" (the last stop-and-go
// event never started, whatever the path did afterwards), "stopped_free" (the final standstill
// began with the path free: a spontaneous stop), "blocked" (it began behind a leader, a light,
// a pedestrian or priority traffic, and no event of a freed path went unanswered). Per step,
// dt apart, the last entries the end; `events` are the StopGoTracker's.
std::string classify_timeout(const std::vector<char>& stopped, const std::vector<char>& path_free,
                             const std::vector<StopGoEvent>& events, double dt);

// The timeout classes, and copycat's share of them (stuck, restart_stall, stopped_free).
const std::vector<std::string>& timeout_classes();
bool is_copycat_class(const std::string& outcome);

struct StopGoEvent {
  double time_s = 0;     // when the path became free with the ego stopped
  double delay_s = 0;    // until the ego exceeded kStoppedSpeed; censored at the episode's
                         // end when it never started (then started == false)
  bool started = false;
  bool stall = false;    // delay above kStallDelay or never started
  std::string kind;      // "start" (free path when the agent took over) or "freed"
};

// Follows one episode step by step. An event opens when the ego is stopped and its path
// becomes free (or is free when the agent takes over); it closes when the ego exceeds
// kStoppedSpeed. If the path is blocked again before the ego started and before kStallDelay,
// the event is dropped (the ego was right to wait); after kStallDelay it stays a stall.
class StopGoTracker {
 public:
  explicit StopGoTracker(double dt) : dt_(dt) {}
  // The state after step `step` (0-based, at time (step + 1) * dt after the takeover).
  void observe(double speed, bool path_free);
  // Closes an open event at the end of the episode.
  void finish();
  const std::vector<StopGoEvent>& events() const { return events_; }

 private:
  double dt_;
  long step_ = 0;
  bool first_ = true;
  bool prev_free_ = false;
  bool open_ = false;
  StopGoEvent cur_;
  std::vector<StopGoEvent> events_;
};

// One evaluated episode (results.json "episodes").
struct EpisodeResult {
  int index = 0, task = 0, trial = 0;
  std::string scenario;
  uint64_t traffic_seed = 0;
  // success | collision | offroad | stuck | restart_stall | stopped_free | blocked | slow |
  // infrastructure_failure (records before the taxonomy: inertia | timeout)
  std::string outcome;
  std::string collided_with;
  std::string collision_kind;    // collisions: "vehicle" or "pedestrian"
  std::string collision_by;      // collisions: "ego" (the ego struck) or "other" (it was struck)
  std::string failure;           // what went wrong, for infrastructure failures
  std::string weather;           // the camera's appearance set (sense.view = "camera" only)
  double route_length_m = 0;
  double distance_m = 0;
  double duration_s = 0;
  int red_light_violations = 0;
  int light_passages = 0;        // junctions entered through a traffic light
  int green_light_entries = 0;   // of them, entered on green (SUMO 'G' or 'g')
  // ego.lateral = "free": wrong-way onsets, lane invasions, mean |lateral error| to the lane
  // centre (m; negative when the ego was never on a lane, and in route mode).
  int wrong_way = 0;
  int lane_invasions = 0;
  int lane_changes = 0;          // changes to a neighbouring lane of the same edge
  double lateral_error_m = -1;
  std::vector<StopGoEvent> events;
  // What decides a timeout's class (results.json "taxonomy"): the time (s after the takeover)
  // of the last change of the path's state and of the start of the final standstill (none
  // while moving at the end), what held the path then (free, leader, red_light, pedestrian,
  // yield, other), the highest speed of each of the last 15 seconds (oldest first), and seed
  // 000's inertia. has_taxonomy is false for a record written before them.
  bool has_taxonomy = true;
  std::optional<double> last_free_change_s, last_stop_s;
  std::string last_stop_cause;
  std::vector<double> final_max_speed;
  bool paper_inertia = false;
  nlohmann::json agent = nlohmann::json::object();  // the agent's episode_figures()

  double route_completion() const;
  double mean_speed() const;
};

// Counts one step's junction entry into the episode: `entered_light` is the TlCode that
// light_at_junction_entry (world/ground_truth.hpp) gave for the step (StepResult::entered_light).
// A light-controlled passage unless kTlNone; entered on green for kTlGreen and kTlGreenYield;
// a red-light violation for kTlRed (yellow is a passage, neither green nor a violation).
void count_junction_entry(EpisodeResult& r, int entered_light);

nlohmann::json episode_to_json(const EpisodeResult& e);
EpisodeResult episode_from_json(const nlohmann::json& j);  // throws DataError

// The summary over episodes (infrastructure failures are counted, never in the rates).
// green_light_rate pools the passages of all episodes (green entries / light-controlled
// passages, so an episode weighs by its passages); null when no episode passed a light.
nlohmann::json summarize(const std::vector<EpisodeResult>& episodes);

// q-quantile (0..1) with linear interpolation; nullopt for no values.
std::optional<double> quantile(std::vector<double> values, double q);

}  // namespace cd
