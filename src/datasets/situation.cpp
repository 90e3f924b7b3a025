#include "datasets/situation.hpp"

#include <algorithm>
#include <cmath>

#include "core/error.hpp"
#include "data/h5_episode.hpp"
#include "world/ground_truth.hpp"

namespace cd {

const std::vector<std::string>& situation_names() {
  static const std::vector<std::string> names = {
      "all",           "standing_free", "starting",        "cruising",
      "slowing_red",   "slowing_other", "following",       "standing_blocked"};
  return names;
}

const std::vector<std::string>& situation_causes() {
  static const std::vector<std::string> names = {"path_free", "tl_state", "tl_distance",
                                                 "lead_present", "lead_distance"};
  return names;
}

bool has_situation_causes(const std::map<std::string, std::vector<float>>& causes) {
  for (const std::string& name : situation_causes())
    if (!causes.count(name)) return false;
  return true;
}

bool records_situation_causes(const std::string& data_dir) {
  return has_situation_causes(read_episode(list_episode_files(data_dir).front()).causes);
}

namespace {

const std::vector<float>& cause(const PackedEpisode& ep, const char* name) {
  auto it = ep.causes.find(name);
  if (it == ep.causes.end() || it->second.size() != static_cast<size_t>(ep.frames))
    throw DataError("episode file " + ep.file + " has no causes/" + name +
                    " (situations need the causes `causaldrive collect` records)");
  return it->second;
}

}  // namespace

uint32_t situations_at(const PackedEpisode& ep, int t, double dt, const SituationRules& r) {
  const auto& path_free = cause(ep, "path_free");
  const auto& tl_state = cause(ep, "tl_state");
  const auto& tl_distance = cause(ep, "tl_distance");
  const auto& lead_present = cause(ep, "lead_present");
  const auto& lead_distance = cause(ep, "lead_distance");
  const double v = ep.speed[t];
  const double accel = ep.frames < 2 ? 0.0
                       : t + 1 < ep.frames ? (ep.speed[t + 1] - ep.speed[t]) / dt
                                           : (ep.speed[t] - ep.speed[t - 1]) / dt;
  const int tl = static_cast<int>(std::lround(tl_state[t]));
  const bool red_ahead = (tl == kTlRed || tl == kTlYellow) &&
                         tl_distance[t] <= v * v / (2.0 * r.red_decel) + r.red_margin;
  const bool free = path_free[t] >= 0.5f;
  const bool leader = lead_present[t] >= 0.5f && lead_distance[t] <= r.lead_within;
  const bool standing = v < r.standing_below;
  uint32_t m = 1u << kAllFrames;
  auto set = [&](Situation s, bool on) {
    if (on) m |= 1u << s;
  };
  set(kStandingFree, standing && free && !red_ahead);
  set(kStarting, v < r.starting_below && accel > r.accel_threshold && free);
  set(kCruising, v >= r.starting_below && std::abs(accel) < r.accel_threshold);
  set(kSlowingRed, accel < -r.accel_threshold && red_ahead);
  set(kSlowingOther, accel < -r.accel_threshold && !red_ahead);
  set(kFollowing, !standing && leader);
  set(kStandingBlocked, standing && (leader || red_ahead));
  return m;
}

}  // namespace cd

namespace cd {

int situation_class(uint32_t mask) {
  static const Situation order[] = {kStarting,        kStandingFree, kSlowingRed, kSlowingOther,
                                    kStandingBlocked, kFollowing,    kCruising};
  for (Situation s : order)
    if ((mask >> s) & 1u) return s;
  return kAllFrames;
}

std::vector<float> balanced_weights(const std::vector<int>& classes, double max_weight) {
  std::vector<long> count(kSituationCount, 0);
  for (int c : classes) ++count.at(static_cast<size_t>(c));
  const double n = static_cast<double>(classes.size());
  const double present =
      static_cast<double>(std::count_if(count.begin(), count.end(), [](long k) { return k > 0; }));
  std::vector<double> w(kSituationCount, 0.0);
  for (int c = 0; c < kSituationCount; ++c)
    if (count[c] > 0) w[c] = std::min(max_weight, n / (present * static_cast<double>(count[c])));
  double sum = 0;
  for (int c : classes) sum += w[c];
  std::vector<float> out;
  out.reserve(classes.size());
  for (int c : classes) out.push_back(static_cast<float>(w[c] * n / sum));
  return out;
}

}  // namespace cd
