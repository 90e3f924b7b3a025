#include "bench/metrics.hpp"

#include <algorithm>
#include <map>
#include <cmath>

#include <nlohmann/json.hpp>

#include "core/error.hpp"
#include "world/ground_truth.hpp"

namespace cd {

double route_timeout_s(double route_length_m) { return route_length_m / (5.0 / 3.6) + 20.0; }

bool is_inertia(const std::vector<char>& stopped, const std::vector<char>& path_free, double dt) {
  const size_t n = std::min(stopped.size(), path_free.size());
  const size_t need = static_cast<size_t>(std::ceil(kInertiaSpan / dt - 1e-9));
  if (need == 0 || n < need) return false;
  for (size_t i = n - need; i < n; ++i)
    if (!stopped[i] || !path_free[i]) return false;
  return true;
}

bool is_paper_inertia(const std::vector<char>& stopped, double dt) {
  const size_t need = static_cast<size_t>(std::ceil(kInertiaSpan / dt - 1e-9));
  if (need == 0 || stopped.size() < need) return false;
  return std::all_of(stopped.end() - static_cast<long>(need), stopped.end(),
                     [](char s) { return s != 0; });
}

const std::vector<std::string>& timeout_classes() {
  static const std::vector<std::string> classes = {"stuck", "restart_stall", "stopped_free",
                                                   "blocked", "slow"};
  return classes;
}

bool is_copycat_class(const std::string& outcome) {
  return outcome == "stuck" || outcome == "restart_stall" || outcome == "stopped_free";
}

std::string classify_timeout(const std::vector<char>& stopped, const std::vector<char>& path_free,
                             const std::vector<StopGoEvent>& events, double dt) {
  if (is_inertia(stopped, path_free, dt)) return "stuck";
  if (stopped.empty() || !stopped.back()) return "slow";
  if (!events.empty() && !events.back().started) return "restart_stall";
  // The final standstill's first step: a stop made with the path free (not the start, where
  // the agent took over a standing ego) is spontaneous.
  size_t k = stopped.size();
  while (k > 0 && stopped[k - 1]) --k;
  if (k > 0 && k < path_free.size() && path_free[k]) return "stopped_free";
  return "blocked";
}

void StopGoTracker::observe(double speed, bool path_free) {
  const double t = static_cast<double>(++step_) * dt_;
  const bool stopped = speed < kStoppedSpeed;
  if (open_) {
    const double elapsed = t - cur_.time_s;
    if (!stopped) {
      cur_.delay_s = elapsed;
      cur_.started = true;
      cur_.stall = elapsed > kStallDelay;
      events_.push_back(cur_);
      open_ = false;
    } else if (!path_free && elapsed <= kStallDelay) {
      open_ = false;  // blocked again before it should have gone: not an event
    }
  } else if (stopped && path_free && (first_ || !prev_free_)) {
    open_ = true;
    cur_ = {};
    cur_.time_s = t;
    cur_.kind = first_ ? "start" : "freed";
  }
  first_ = false;
  prev_free_ = path_free;
}

void StopGoTracker::finish() {
  if (!open_) return;
  const double t = static_cast<double>(step_) * dt_;
  cur_.delay_s = t - cur_.time_s;
  cur_.started = false;
  // An event cut short by the end of the episode within kStallDelay says nothing.
  if (cur_.delay_s > kStallDelay) {
    cur_.stall = true;
    events_.push_back(cur_);
  }
  open_ = false;
}

void count_junction_entry(EpisodeResult& r, int entered_light) {
  if (entered_light == kTlNone) return;
  ++r.light_passages;
  r.green_light_entries += entered_light == kTlGreen || entered_light == kTlGreenYield;
  r.red_light_violations += entered_light == kTlRed;
}

double EpisodeResult::route_completion() const {
  return route_length_m > 0 ? std::clamp(distance_m / route_length_m, 0.0, 1.0) : 0.0;
}

double EpisodeResult::mean_speed() const { return duration_s > 0 ? distance_m / duration_s : 0.0; }

nlohmann::json episode_to_json(const EpisodeResult& e) {
  nlohmann::json ev = nlohmann::json::array();
  for (const StopGoEvent& s : e.events)
    ev.push_back({{"time_s", s.time_s}, {"delay_s", s.delay_s}, {"started", s.started},
                  {"stall", s.stall}, {"kind", s.kind}});
  nlohmann::json j = {{"index", e.index},
                      {"task", e.task},
                      {"trial", e.trial},
                      {"scenario", e.scenario},
                      {"traffic_seed", e.traffic_seed},
                      {"outcome", e.outcome},
                      {"route_length_m", e.route_length_m},
                      {"distance_m", e.distance_m},
                      {"route_completion", e.route_completion()},
                      {"duration_s", e.duration_s},
                      {"mean_speed", e.mean_speed()},
                      {"red_light_violations", e.red_light_violations},
                      {"light_passages", e.light_passages},
                      {"green_light_entries", e.green_light_entries},
                      {"stop_go_events", ev},
                      {"wrong_way", e.wrong_way},
                      {"lane_invasions", e.lane_invasions},
                      {"lane_changes", e.lane_changes}};
  if (e.lateral_error_m >= 0) j["lateral_error_m"] = e.lateral_error_m;
  if (!e.collided_with.empty()) j["collided_with"] = e.collided_with;
  if (!e.collision_kind.empty()) j["collision_kind"] = e.collision_kind;
  if (!e.collision_by.empty()) j["collision_by"] = e.collision_by;
  if (!e.failure.empty()) j["failure"] = e.failure;
  if (!e.weather.empty()) j["weather"] = e.weather;
  if (!e.agent.empty()) j["agent"] = e.agent;
  if (e.has_taxonomy && e.outcome != "infrastructure_failure") {
    auto opt = [](const std::optional<double>& x) {
      return x ? nlohmann::json(*x) : nlohmann::json();
    };
    j["taxonomy"] = {{"last_free_change_s", opt(e.last_free_change_s)},
                     {"last_stop_s", opt(e.last_stop_s)},
                     {"last_stop_cause", e.last_stop_cause.empty()
                                             ? nlohmann::json()
                                             : nlohmann::json(e.last_stop_cause)},
                     {"final_max_speed", e.final_max_speed},
                     {"paper_inertia", e.paper_inertia}};
  }
  return j;
}

EpisodeResult episode_from_json(const nlohmann::json& j) {
  try {
    EpisodeResult e;
    e.index = j.at("index").get<int>();
    e.task = j.at("task").get<int>();
    e.trial = j.at("trial").get<int>();
    e.scenario = j.at("scenario").get<std::string>();
    e.traffic_seed = j.at("traffic_seed").get<uint64_t>();
    e.outcome = j.at("outcome").get<std::string>();
    e.route_length_m = j.at("route_length_m").get<double>();
    e.distance_m = j.at("distance_m").get<double>();
    e.duration_s = j.at("duration_s").get<double>();
    e.red_light_violations = j.at("red_light_violations").get<int>();
    e.light_passages = j.at("light_passages").get<int>();
    e.green_light_entries = j.at("green_light_entries").get<int>();
    e.collided_with = j.value("collided_with", "");
    e.collision_kind = j.value("collision_kind", "");
    e.collision_by = j.value("collision_by", "");
    e.failure = j.value("failure", "");
    e.weather = j.value("weather", "");
    e.agent = j.value("agent", nlohmann::json::object());
    e.wrong_way = j.value("wrong_way", 0);
    e.lane_invasions = j.value("lane_invasions", 0);
    e.lane_changes = j.value("lane_changes", 0);
    e.lateral_error_m = j.value("lateral_error_m", -1.0);
    e.has_taxonomy = j.contains("taxonomy") || e.outcome == "infrastructure_failure";
    if (j.contains("taxonomy")) {
      const nlohmann::json& t = j.at("taxonomy");
      auto opt = [&](const char* k) {
        return t.at(k).is_null() ? std::optional<double>() : t.at(k).get<double>();
      };
      e.last_free_change_s = opt("last_free_change_s");
      e.last_stop_s = opt("last_stop_s");
      e.last_stop_cause = t.at("last_stop_cause").is_null() ? "" : t.at("last_stop_cause");
      e.final_max_speed = t.at("final_max_speed").get<std::vector<double>>();
      e.paper_inertia = t.at("paper_inertia").get<bool>();
    }
    for (const auto& s : j.at("stop_go_events")) {
      StopGoEvent ev;
      ev.time_s = s.at("time_s").get<double>();
      ev.delay_s = s.at("delay_s").get<double>();
      ev.started = s.at("started").get<bool>();
      ev.stall = s.at("stall").get<bool>();
      ev.kind = s.at("kind").get<std::string>();
      e.events.push_back(ev);
    }
    return e;
  } catch (const nlohmann::json::exception& ex) {
    throw DataError(std::string("malformed episode record: ") + ex.what());
  }
}

std::optional<double> quantile(std::vector<double> v, double q) {
  if (v.empty()) return std::nullopt;
  std::sort(v.begin(), v.end());
  const double pos = q * static_cast<double>(v.size() - 1);
  const size_t lo = static_cast<size_t>(std::floor(pos));
  const size_t hi = std::min(lo + 1, v.size() - 1);
  return v[lo] + (v[hi] - v[lo]) * (pos - static_cast<double>(lo));
}

nlohmann::json summarize(const std::vector<EpisodeResult>& episodes) {
  long n = 0, failures = 0, success = 0, collision = 0, inertia = 0, timeout = 0, red = 0;
  long vehicle_hits = 0, pedestrian_hits = 0, ego_struck = 0;
  long events = 0, stalls = 0, passages = 0, green = 0, offroad = 0, wrong_way = 0, invasions = 0,
       changes = 0;
  double lateral_sum = 0;
  long lateral_n = 0;
  double km = 0, completion = 0, distance = 0, duration = 0;
  std::vector<double> delays;
  std::map<std::string, std::pair<double, long>> agent;  // numeric agent figures: sum, count
  std::map<std::string, long> classes;  // the timeout classes (SPEC section 14)
  for (const std::string& c : timeout_classes()) classes[c] = 0;
  long paper_inertia = 0;
  for (const EpisodeResult& e : episodes) {
    if (e.outcome == "infrastructure_failure") {
      ++failures;
      continue;
    }
    ++n;
    success += e.outcome == "success";
    collision += e.outcome == "collision";
    if (e.outcome == "collision") {
      vehicle_hits += e.collision_kind == "vehicle";
      pedestrian_hits += e.collision_kind == "pedestrian";
      ego_struck += e.collision_by == "ego";
    }
    // Records before the taxonomy: "inertia" is today's stuck, "timeout" any other class.
    const std::string cls = e.outcome == "inertia" ? "stuck" : e.outcome;
    if (classes.count(cls)) ++classes[cls];
    inertia += cls == "stuck";
    timeout += cls != "stuck" && (classes.count(cls) || cls == "timeout");
    paper_inertia += e.paper_inertia;
    offroad += e.outcome == "offroad";
    wrong_way += e.wrong_way;
    invasions += e.lane_invasions;
    changes += e.lane_changes;
    if (e.lateral_error_m >= 0) {
      lateral_sum += e.lateral_error_m;
      ++lateral_n;
    }
    red += e.red_light_violations;
    passages += e.light_passages;
    green += e.green_light_entries;
    km += e.distance_m / 1000.0;
    completion += e.route_completion();
    distance += e.distance_m;
    duration += e.duration_s;
    for (const auto& [key, value] : e.agent.items())
      if (value.is_number()) {
        agent[key].first += value.get<double>();
        ++agent[key].second;
      }
    for (const StopGoEvent& s : e.events) {
      ++events;
      stalls += s.stall;
      delays.push_back(s.delay_s);
    }
  }
  auto rate = [n](long k) { return n > 0 ? static_cast<double>(k) / n : 0.0; };
  auto opt = [](std::optional<double> x) { return x ? nlohmann::json(*x) : nlohmann::json(); };
  nlohmann::json summary = {{"episodes", n},
          {"infrastructure_failures", failures},
          {"success_rate", rate(success)},
          {"collision_rate", rate(collision)},
          // The taxonomy of timeouts (SPEC section 14): with success, collision and off-road
          // they sum to 1. copycat = stuck + restart_stall + stopped_free.
          {"stuck_rate", rate(classes["stuck"])},
          {"restart_stall_rate", rate(classes["restart_stall"])},
          {"stopped_free_rate", rate(classes["stopped_free"])},
          {"blocked_rate", rate(classes["blocked"])},
          {"slow_rate", rate(classes["slow"])},
          {"copycat_rate",
           rate(classes["stuck"] + classes["restart_stall"] + classes["stopped_free"])},
          // inertia is the SPEC's rule of section 5 (the stuck class), timeout every other
          // episode that ran out of time, as in the tables before the taxonomy.
          {"inertia_rate", rate(inertia)},
          {"timeout_rate", rate(timeout)},
          // Every episode that ran out of time, inertia included: seed 001's #TIMEOUT.
          {"time_limit_rate", rate(timeout + inertia)},
          {"error_rate", rate(collision + inertia)},
          // Collisions by kind and by who struck (records before the kinds existed have none),
          // and seed 000's inertia (stood the last 15 s, whatever the path) and error: its
          // inertia + collisions with vehicles.
          {"vehicle_collision_rate", rate(vehicle_hits)},
          {"pedestrian_collision_rate", rate(pedestrian_hits)},
          {"ego_struck_collision_rate", rate(ego_struck)},
          {"paper_inertia_rate", rate(paper_inertia)},
          {"paper_error_rate", rate(paper_inertia + vehicle_hits)},
          {"stop_go_events", events},
          {"stalls", stalls},
          {"stall_rate", events > 0 ? static_cast<double>(stalls) / events : 0.0},
          {"start_delay_median_s", opt(quantile(delays, 0.5))},
          {"start_delay_p90_s", opt(quantile(delays, 0.9))},
          {"red_light_violations_per_km", km > 0 ? red / km : 0.0},
          {"light_passages", passages},
          {"green_light_entries", green},
          {"green_light_rate", passages > 0 ? nlohmann::json(static_cast<double>(green) / passages)
                                            : nlohmann::json()},
          {"route_completion", n > 0 ? completion / n : 0.0},
          {"mean_speed", duration > 0 ? distance / duration : 0.0},
          {"distance_km", km},
          // A free-steering ego (ego.lateral = "free"): leaving the road ends an episode
          // (reported beside error = collision + inertia), wrong-way onsets and lane
          // invasions per km, the episodes' mean |lateral error| (null in route mode).
          {"offroad_rate", rate(offroad)},
          {"wrong_way_per_km", km > 0 ? wrong_way / km : 0.0},
          {"lane_invasions_per_km", km > 0 ? invasions / km : 0.0},
          {"lane_changes_per_km", km > 0 ? changes / km : 0.0},
          {"mean_lateral_error_m", lateral_n > 0 ? nlohmann::json(lateral_sum / lateral_n)
                                                 : nlohmann::json()}};
  // The agent's own figures (dim/rip: how far the planner moves its plans), episode means.
  if (!agent.empty()) {
    nlohmann::json a = nlohmann::json::object();
    for (const auto& [key, sc] : agent) a[key] = sc.first / static_cast<double>(sc.second);
    summary["agent"] = a;
  }
  return summary;
}

}  // namespace cd
