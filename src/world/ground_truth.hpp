#pragma once
// The ground-truth causes of the ego's situation: what the expert acts on, what datasets
// record beside the observation (never given to agents) and what defines "path free", hence
// inertia. Computed by a pure function of the path, the road users and the junction's state,
// so tests can call it without SUMO; the recorded schema is declared here once.
#include <functional>
#include <string>
#include <vector>

#include "core/geometry.hpp"
#include "world/route_path.hpp"
#include "world/world_settings.hpp"

namespace cd {

// High-level command at the next junction (the CIL convention, our numbering).
enum Command : int32_t { kFollow = 0, kLeft = 1, kRight = 2, kStraight = 3 };

// Traffic-light state codes recorded in causes/tl_state.
enum TlCode : int { kTlNone = 0, kTlRed = 1, kTlYellow = 2, kTlGreen = 3, kTlGreenYield = 4 };

// SUMO's link state character -> TlCode; SUMO's direction character -> Command.
int tl_code(char state);
int command_of(char direction);
// A link without priority (SUMO's lower-case states and 'O', off): who uses it yields.
bool is_minor_link(char state);

struct Actor {
  std::string id;
  Box box;
  double speed = 0;
  bool pedestrian = false;
  double accel = 0;  // m/s^2 over the last step (0 in its first step in view)
};

struct GroundTruth {
  bool lead_present = false;
  double lead_distance = 0;   // m from the ego's front to the first vehicle on its path
  double lead_speed = 0;      // m/s, along the path
  int tl_state = kTlNone;     // of the ego's next link
  double tl_distance = 0;     // m to that stop line
  bool ped_on_path = false;
  double ped_distance = 0;    // m, first pedestrian on (or about to step on) the path
  bool must_yield = false;    // priority traffic or pedestrians hold the next junction
  double yield_distance = 0;  // m to where the ego must wait when must_yield
  double junction_distance = 0;  // m to the next junction entry (0 inside one)
  double junction_exit_distance = 0;  // m to the end of that junction
  double path_free_distance = 0; // m checked for path_free
  bool path_free = true;
};

// The recorded schema: one float32 series per entry in an episode's group causes/, in this
// (alphabetical, file) order. A distance whose object is absent is recorded as
// kAbsentDistance.
inline constexpr double kAbsentDistance = 100.0;
struct CauseSeries {
  const char* name;
  double (*value)(const GroundTruth&);
};
const std::vector<CauseSeries>& cause_schema();

// What the truth of one step is computed from.
struct TruthInputs {
  const RoadNetwork& net;
  const RoutePath& path;
  const std::vector<Actor>& actors;
  Pose2 ego_pose;
  double ego_speed = 0;
  double ego_width = 0;
  const WorldSettings& settings;  // margins, path_free_* and command_horizon
  // The current state of a connection (its light's, or its fixed one).
  std::function<char(const ViaInfo&)> link_state;
  // Must a car about to use this internal lane wait (minor: the ego's link has no priority)?
  std::function<bool(const std::string& lane, bool minor)> junction_lane_blocked;
  double ego_length = 4.5;  // ego_pose is the box centre; its front is length / 2 ahead
};

struct TruthStep {
  GroundTruth truth;
  int command = kFollow;
  // The first signalised link on the path: its state and distance (0 and 1e9 when none), so
  // that the next step can tell whether the ego entered it on red.
  char next_light_state = 0;
  double next_light_distance = 1e9;
};

TruthStep compute_ground_truth(const TruthInputs& in);

// Junction entries through a light (SPEC section 5: red-light violations and traffic-light
// compliance), one detection for both. A step entered a light-controlled junction when the ego
// was on a normal lane before it (`prev_lane`) and is on a junction's internal lane after it
// (`lane`; internal lane ids start with ':'), and the first signalised link of its path was
// less than kLightEntryReach m ahead before the step (TruthStep::next_light_state and
// next_light_distance of the previous step). Returns that link's TlCode as it was before the
// step (kTlRed: a violation; kTlGreen or kTlGreenYield: entered on green), or kTlNone when the
// step entered no junction, or one without a light (or with its light off).
inline constexpr double kLightEntryReach = 10.0;
int light_at_junction_entry(const std::string& prev_lane, const std::string& lane,
                            char prev_light_state, double prev_light_distance);

}  // namespace cd
