#include "world/ground_truth.hpp"

#include <algorithm>
#include <cmath>

#include "world/collision.hpp"

namespace cd {

namespace {
constexpr double kStandingSpeed = 0.1;  // m/s: a pedestrian slower than this stands
}  // namespace

int tl_code(char state) {
  switch (state) {
    case 'r': case 'R': case 'u': case 's': return kTlRed;
    case 'y': case 'Y': return kTlYellow;
    case 'G': return kTlGreen;
    case 'g': return kTlGreenYield;
    default: return kTlNone;
  }
}

int light_at_junction_entry(const std::string& prev_lane, const std::string& lane,
                            char prev_light_state, double prev_light_distance) {
  const bool was_internal = !prev_lane.empty() && prev_lane[0] == ':';
  const bool now_internal = !lane.empty() && lane[0] == ':';
  if (!now_internal || was_internal || !(prev_light_distance < kLightEntryReach)) return kTlNone;
  return tl_code(prev_light_state);
}

bool is_minor_link(char state) { return !(state >= 'A' && state <= 'Z') || state == 'O'; }

int command_of(char direction) {
  switch (direction) {
    case 'l': case 'L': case 't': return kLeft;
    case 'r': case 'R': return kRight;
    case 's': return kStraight;
    default: return kFollow;
  }
}

const std::vector<CauseSeries>& cause_schema() {
  static const std::vector<CauseSeries> schema = {
      {"junction_distance", [](const GroundTruth& g) { return g.junction_distance; }},
      {"lead_distance",
       [](const GroundTruth& g) { return g.lead_present ? g.lead_distance : kAbsentDistance; }},
      {"lead_present", [](const GroundTruth& g) { return double(g.lead_present); }},
      {"lead_speed", [](const GroundTruth& g) { return g.lead_present ? g.lead_speed : 0.0; }},
      {"must_yield", [](const GroundTruth& g) { return double(g.must_yield); }},
      {"path_free", [](const GroundTruth& g) { return double(g.path_free); }},
      {"ped_distance",
       [](const GroundTruth& g) { return g.ped_on_path ? g.ped_distance : kAbsentDistance; }},
      {"ped_on_path", [](const GroundTruth& g) { return double(g.ped_on_path); }},
      {"tl_distance",
       [](const GroundTruth& g) { return g.tl_state != kTlNone ? g.tl_distance : kAbsentDistance; }},
      {"tl_state", [](const GroundTruth& g) { return double(g.tl_state); }},
  };
  return schema;
}

TruthStep compute_ground_truth(const TruthInputs& in) {
  TruthStep out;
  GroundTruth& gt = out.truth;
  const WorldSettings& ws = in.settings;
  const RoutePath& path = in.path;
  // What the ego's own body would sweep along the path, plus a margin.
  const double half_body = in.ego_width / 2;

  for (const Actor& a : in.actors) {
    double s_min = 1e300;
    double hw = half_body + (a.pedestrian ? ws.ped_margin : ws.vehicle_margin);
    // Nothing of this actor can be near the path: skip the per-segment tests.
    // (A pedestrian may also be in the corridor straight ahead of the ego, off the path.)
    const double reach = hw + (a.box.length + a.box.width) / 2 + a.speed * ws.ped_lookahead_s +
                         (a.pedestrian ? ws.ped_ahead_m + in.ego_length : 0.0);
    if (a.box.center.x < path.min.x - reach || a.box.center.x > path.max.x + reach ||
        a.box.center.y < path.min.y - reach || a.box.center.y > path.max.y + reach)
      continue;
    auto corners = box_corners(a.box);
    auto test = [&](Vec2 p) {
      double s;
      if (path.locate(p, hw, &s)) s_min = std::min(s_min, s);
    };
    test(a.box.center);
    if (a.pedestrian) {
      Vec2 dir{std::cos(a.box.heading), std::sin(a.box.heading)};
      const Vec2 ahead = a.box.center + dir * (a.speed * ws.ped_lookahead_s);
      test(ahead);
      // The corridor straight ahead of the ego's own body, wherever the path runs: as far as
      // it drives in ped_lookahead_s, plus 1 m, at most ped_ahead_m.
      // A standing pedestrian off the path is in it only close to the body's side: one
      // waiting at the kerb for the ego to pass would otherwise hold it for good.
      const double corridor = std::min(ws.ped_ahead_m, 1.0 + in.ego_speed * ws.ped_lookahead_s);
      const double side = a.speed < kStandingSpeed ? half_body + ws.ped_standing_margin : hw;
      for (Vec2 p : {a.box.center, ahead}) {
        const Vec2 e = to_ego_frame(in.ego_pose, p);
        const double front = e.x - in.ego_length / 2;
        if (front >= -in.ego_length && front <= corridor && std::abs(e.y) <= side)
          s_min = std::min(s_min, std::max(0.0, front));
      }
    } else {
      for (const Vec2& c : corners) test(c);
    }
    if (s_min >= 1e300) continue;
    // Distance from the ego's front: a vehicle overlapping it laterally counts from 0.
    if (a.pedestrian) {
      if (!gt.ped_on_path || s_min < gt.ped_distance) {
        gt.ped_on_path = true;
        gt.ped_distance = s_min;
      }
    } else if (!gt.lead_present || s_min < gt.lead_distance) {
      gt.lead_present = true;
      gt.lead_distance = s_min;
      double rel = a.box.heading - in.ego_pose.heading;
      gt.lead_speed = a.speed * std::cos(rel);
    }
  }

  // The first signalised link on the path ahead: not the junction lane the ego is in (the
  // path's first lane), but one that begins right at its front (s_begin 0: the ego stands at
  // the very end of its approach lane, as a free ego's SUMO stand-in often does for a step).
  for (const PathLane& pl : path.lanes) {
    if (&pl == &path.lanes.front() || pl.s_begin < 0 || !pl.lane->internal) continue;
    const ViaInfo* vi = in.net.find_via(pl.lane->id);
    if (!vi || vi->tls.empty()) continue;
    char state = in.link_state(*vi);
    gt.tl_state = tl_code(state);
    gt.tl_distance = pl.s_begin;
    out.next_light_state = state;
    out.next_light_distance = pl.s_begin;
    break;
  }

  // The next junction on the path (or the one the ego is in): its internal lanes, the
  // approach lane before them, and the state and direction of the ego's link.
  const std::vector<PathLane>& lanes = path.lanes;
  size_t j0 = lanes.size();
  for (size_t i = 0; i < lanes.size(); ++i)
    if (lanes[i].lane->internal) {
      j0 = i;
      break;
    }
  gt.junction_distance = j0 < lanes.size() ? lanes[j0].s_begin : 0.0;
  gt.junction_exit_distance = 0;
  if (j0 < lanes.size()) {
    size_t j1 = j0;
    while (j1 < lanes.size() && lanes[j1].lane->internal) ++j1;
    gt.junction_exit_distance =
        j1 < lanes.size() ? lanes[j1].s_begin
                          : lanes[j1 - 1].s_begin + lanes[j1 - 1].lane->length - lanes[j1 - 1].from_pos;
    const bool inside = j0 == 0;
    const ViaInfo* vi = in.net.find_via(in.net.via_of(lanes[j0].lane->id));
    const char dir = vi ? vi->direction : 's';
    const char state = vi ? in.link_state(*vi) : 'O';
    if (inside || gt.junction_distance <= ws.command_horizon) out.command = command_of(dir);
    // The ego decides at the junction's entry for all of its internal lanes; once inside it
    // is committed (waiting in the middle would leave it standing in other cars' paths).
    const bool minor = is_minor_link(state);
    for (size_t j = j0; !inside && j < j1 && !gt.must_yield; ++j) {
      if (in.junction_lane_blocked(lanes[j].lane->id, minor)) {
        gt.must_yield = true;
        gt.yield_distance = gt.junction_distance;
      }
    }
  }

  // Path free: nothing within the stopping distance at path_free_decel plus the margin. These
  // are benchmark settings ([world]), never the expert's comfort: they define inertia.
  double v = in.ego_speed;
  gt.path_free_distance = v * v / (2 * ws.path_free_decel) + ws.path_free_margin;
  const double d = gt.path_free_distance;
  gt.path_free = !(gt.lead_present && gt.lead_distance < d) &&
                 !((gt.tl_state == kTlRed || gt.tl_state == kTlYellow) && gt.tl_distance < d) &&
                 !(gt.ped_on_path && gt.ped_distance < d) &&
                 !(gt.must_yield && gt.yield_distance < d);
  return out;
}


}  // namespace cd
