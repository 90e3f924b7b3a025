#include "datasets/ground_truth.hpp"

#include <algorithm>
#include <cmath>

#include "world/ground_truth.hpp"

namespace cd {

namespace {
// The analysis view of the recorded causes (datasets/ground_truth.hpp).
constexpr double kLeadDistanceCap = 60.0;  // m: no leader reads as one this far away
constexpr double kRedLightNear = 30.0;     // m: a red or yellow light nearer than this counts
}  // namespace

const std::vector<std::string>& ground_truth_names() {
  static const std::vector<std::string> names = {"lead_distance", "lead_present", "red_light",
                                                 "path_free", "ped_on_path"};
  return names;
}

double ground_truth_value(const PackedEpisode& ep, const std::string& name, int t) {
  const double nan = std::nan("");
  auto get = [&](const char* key) -> const std::vector<float>* {
    auto it = ep.causes.find(key);
    if (it == ep.causes.end() || static_cast<int>(it->second.size()) <= t) return nullptr;
    return &it->second;
  };
  if (name == "lead_distance") {
    const auto* d = get("lead_distance");
    const auto* present = get("lead_present");
    if (!d) return nan;
    if (present && (*present)[t] == 0) return kLeadDistanceCap;
    double v = (*d)[t];
    return std::isfinite(v) ? std::min(v, kLeadDistanceCap) : kLeadDistanceCap;
  }
  if (name == "red_light") {
    const auto* s = get("tl_state");
    const auto* d = get("tl_distance");
    if (!s || !d) return nan;
    const int state = static_cast<int>(std::lround((*s)[t]));
    return (state == kTlRed || state == kTlYellow) && (*d)[t] < kRedLightNear ? 1.0 : 0.0;
  }
  if (name == "path_free") {
    const auto* v = get("path_free");
    if (v) return (*v)[t];
    if (static_cast<int>(ep.path_free.size()) > t) return ep.path_free[t];
    return nan;
  }
  const auto* v = get(name.c_str());
  return v ? static_cast<double>((*v)[t]) : nan;
}

}  // namespace cd
