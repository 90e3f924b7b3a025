#pragma once
// One SUMO simulation in this process (libsumo allows one per process): the mutable state
// over an immutable RoadMap. Reset to a Task, step the ego with throttle/brake, read what
// the sensors, the checks and the (privileged) expert need.
#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <unordered_map>
#include <unordered_set>
#include <vector>

#include <libsumo/TraCIDefs.h>

#include "app/settings.hpp"
#include "core/geometry.hpp"
#include "sense/bev.hpp"
#include "world/ego_model.hpp"
#include "world/road_map.hpp"

namespace cd {

struct Task {
  std::vector<std::string> route;  // edge ids, start to goal
  int start_lane = -1;             // lane index on the first edge (-1: SUMO's best)
  double start_pos = 0;            // m along the first edge
  double goal_pos = 0;             // m along the last edge
  uint64_t traffic_seed = 0;
  double route_length = 0;         // m from start to goal along the route
  double timeout_s = 0;            // route at 5 km/h + 20 s unless set otherwise
  // How the episode starts (SPEC section 5, interaction suites):
  //   route     the ego starts stopped on its route, traffic around;
  //   red_light the ego starts stopped first in line at the stop line of a light that has
  //             just turned red;
  //   leader    the ego starts stopped leader_gap m behind a stopped car on its lane that
  //             drives off (SUMO's driver) leader_hold_s after the ego entered.
  std::string scenario = "route";
  double leader_gap = 0;
  double leader_hold_s = 0;
};

// Scenario names of Task::scenario.
const std::vector<std::string>& scenario_names();

enum class Outcome { Running, Success, Collision, Timeout };
const char* outcome_name(Outcome o);

// High-level command at the next junction (the CIL convention, our numbering).
enum Command : int32_t { kFollow = 0, kLeft = 1, kRight = 2, kStraight = 3 };

struct Actor {
  std::string id;
  Box box;
  double speed = 0;
  bool pedestrian = false;
};

// Traffic-light state codes recorded in causes/tl_state.
enum TlCode : int { kTlNone = 0, kTlRed = 1, kTlYellow = 2, kTlGreen = 3, kTlGreenYield = 4 };

// Privileged facts about the ego's situation, recomputed after every step. They are what the
// expert acts on and what datasets record as ground-truth causes; agents never see them.
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

struct EgoState {
  Pose2 pose;            // centre of the ego box
  double speed = 0;      // m/s
  double accel = 0;      // m/s^2 of the last step
  std::string lane;
  double lane_pos = 0;   // m of the front bumper along its lane
  double lane_speed_limit = 13.89;
  double progress = 0;   // m driven along the route since the start
  double time = 0;       // s since the ego entered
};

struct StepResult {
  Outcome outcome = Outcome::Running;
  std::string collided_with;  // actor id when outcome == Collision
  bool ran_red_light = false; // this step entered a junction on red
};

struct WorldCounters {
  int red_light_violations = 0;
  double distance = 0;  // m driven
};

class World {
 public:
  explicit World(const Settings& settings);  // starts SUMO on the configured network
  ~World();
  World(const World&) = delete;
  World& operator=(const World&) = delete;

  // A random task on this network: route length within [min_len, max_len] where possible.
  Task sample_task(uint64_t seed, double min_len, double max_len);
  // A random task of a scenario (see Task). Throws SimError when the network has no place
  // for it (no traffic light for red_light, no edge long enough for leader).
  Task sample_scenario_task(uint64_t seed, const std::string& scenario, double min_len,
                            double max_len);

  // Reloads the simulation, spawns and warms up background traffic, inserts the ego stopped
  // at the route start. Throws SimError when SUMO fails.
  void reset(const Task& task);

  // Applies the control for one step of dt and runs the checks.
  StepResult step(const Control& c);

  // The benchmark's baseline: SUMO's own driver model takes the ego back, and step_bare()
  // advances SUMO alone (with the same background refills as step()).
  void hand_ego_to_sumo();
  void step_bare();

  void render(uint8_t* out) const;         // the BEV of the current state, C*H*W bytes
  void render_packed(uint8_t* out) const;  // the same as H*W bytes of channel bits
  BevScene scene() const;

  const EgoState& ego() const { return ego_; }
  const GroundTruth& truth() const { return truth_; }
  int command() const { return command_; }
  const Task& task() const { return task_; }
  const WorldCounters& counters() const { return counters_; }
  const std::vector<Actor>& actors() const { return actors_; }
  const RoadMap& map() const { return map_; }
  const Settings& settings() const { return settings_; }
  const EgoModel& ego_model() const { return ego_model_; }
  const BevRenderer& renderer() const { return *renderer_; }
  const std::string& network_path() const { return net_path_; }
  double time() const { return ego_.time; }
  // Path lanes of the current route from the ego on (ids), for the route layer and tests.
  const std::vector<std::string>& route_lanes() const { return route_lanes_; }
  // The point of the ego's path `s` metres ahead of its front bumper (network frame), or its
  // last point when the path known this step (80 m, or up to the goal) is shorter.
  Vec2 path_point(double s) const;

  // Test hooks: place a stopped vehicle on a lane position (scripted scenarios), and read
  // the per-step collision and red-light state.
  std::string add_scripted_vehicle(const std::string& lane_id, double pos, double speed);
  void set_vehicle_speed(const std::string& id, double speed);

 private:
  struct Link {
    std::string to_lane, via_lane;
    char direction = 's';
  };
  // A connection through a junction, keyed by its first internal lane (the via).
  struct ViaInfo {
    std::string approach;   // the normal lane it leaves from
    char direction = 's';   // SUMO's s, l, r, ...
    char fixed_state = 'O'; // state of an unsignalised link (M, m, =, ...)
    std::string tls;        // the light controlling it, if any
    int tls_index = -1;     // its index in that light's state string
  };
  struct PathLane {
    const LaneGeom* lane = nullptr;
    double from_pos = 0;  // lane position where the ego's path enters this lane
    double s_begin = 0;   // distance along the path (from the ego's front) of from_pos
  };

  std::vector<std::string> sumo_args(uint64_t seed) const;
  void build_map();
  void spawn_background();
  void top_up_background();
  bool add_background_car(const std::string& id);
  void insert_ego();
  // red_light: runs the simulation until the light of the ego's first link turns red.
  void wait_for_red_onset();
  // The first link of a task's route from its start lane: its via lane ("" if none).
  std::string first_via(const Task& task) const;
  void advance();  // one SUMO step plus the periodic background refill
  void refresh();  // reads SUMO state, recomputes actors, path, truth, command
  void compute_path();
  void compute_truth();
  bool on_path(Vec2 p, double half_width, double* s) const;
  const std::string& via_head(const std::string& internal_lane) const;
  const ViaInfo* via_info(const std::string& via) const;
  char link_state(const ViaInfo& vi);  // current state of the link (light or fixed)
  const std::vector<std::string>& internal_foes(const std::string& lane);
  // Must a car about to use this internal lane wait (pedestrians on or heading for a foe
  // crossing, cars in the conflict area, priority cars arriving when the ego's link is minor)?
  bool junction_lane_blocked(const std::string& lane, bool minor);
  StepResult check_events(bool ego_present);
  std::vector<std::string> route_lane_sequence() const;
  std::vector<std::unordered_set<std::string>> lane_plan(
      const std::vector<std::string>& route) const;
  // The lane of `to_edge` reached from `lane` (its via lane when it has one), preferring
  // lanes in `good`; "" when there is no connection.
  std::string next_lane(const std::string& lane, const std::string& to_edge,
                        const std::unordered_set<std::string>* good) const;
  // The lane after `lane` along the task's route; k tracks the route edge index.
  std::string lane_after(const std::string& lane, size_t& k) const;

  Settings settings_;
  EgoModel ego_model_;
  std::string net_path_;
  RoadMap map_;
  std::unique_ptr<BevRenderer> renderer_;
  std::unordered_map<std::string, std::vector<Link>> links_;       // lane -> outgoing links
  std::unordered_map<std::string, ViaInfo> via_info_;
  std::unordered_map<std::string, std::string> tls_states_;  // this step's light states
  long tls_cache_step_ = -1;
  std::unordered_map<std::string, std::string> via_head_;          // internal lane -> its via
  std::unordered_map<std::string, std::vector<std::string>> foes_; // internal lane -> foe lanes
  std::unordered_map<std::string, const LaneGeom*> edge_lane_;  // car edge -> rightmost car lane
  std::unordered_map<std::string, std::vector<std::string>> edge_lanes_;  // car edge -> lanes
  std::vector<std::unordered_set<std::string>> plan_;  // lane plan of the current task
  std::unordered_map<std::string, size_t> sidewalk_of_edge_;    // edge -> its sidewalk lane
  std::vector<std::string> car_edges_;  // normal edges with a lane for cars
  std::vector<std::string> ped_edges_;  // normal edges with a sidewalk
  double lane_km_ = 0;                  // km of driving lane (traffic scales with it)

  Task task_;
  std::unique_ptr<class Rng> traffic_rng_;
  int target_cars_ = 0, target_peds_ = 0, next_actor_id_ = 0, scripted_ = 0;
  double ego_entry_time_ = 0;
  long steps_since_load_ = 0;
  EgoState ego_;
  GroundTruth truth_;
  int command_ = kFollow;
  WorldCounters counters_;
  std::vector<Actor> actors_;
  std::vector<PathLane> path_;
  std::vector<std::string> route_lanes_;
  Vec2 path_min_, path_max_;              // bounding box of the path's lanes
  // Road users within view_radius after the last step (SUMO's context subscription).
  std::map<std::string, std::map<int, std::shared_ptr<libsumo::TraCIResult>>> nearby_;
  char prev_link_state_ = 0;
  double prev_link_distance_ = 1e9;
  bool ego_present_ = false;
  bool leader_held_ = false;  // leader scenario: the leader still waits
  Outcome outcome_ = Outcome::Running;
};

}  // namespace cd
