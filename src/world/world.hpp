#pragma once
// One SUMO simulation in this process (libsumo allows one per process): the mutable session
// (MuJoCo's mjData) over the immutable RoadNetwork of its town (the mjModel,
// world/road_network.hpp). Reset to a Task, step the ego with throttle/brake, read what the
// sensors, the checks and the (privileged) expert need. Path geometry and the ground truth are
// pure functions (world/route_path.hpp, world/ground_truth.hpp); libsumo stays in world.cpp.
#include <cstdint>
#include <memory>
#include <string>
#include <unordered_map>
#include <vector>

#include "core/geometry.hpp"
#include "sense/bev.hpp"
#include "sense/camera.hpp"
#include "world/ego_model.hpp"
#include "world/ground_truth.hpp"
#include "world/lane_contact.hpp"
#include "world/road_network.hpp"
#include "world/route_path.hpp"
#include "world/world_settings.hpp"

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

enum class Outcome { Running, Success, Collision, Timeout, Offroad };
const char* outcome_name(Outcome o);

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
  std::string collision_kind; // "vehicle" or "pedestrian" when outcome == Collision
  bool ego_struck = false;    // the ego struck the other (a_strikes), else it was struck
  bool ran_red_light = false; // this step entered a junction on red
  // The light (TlCode) of the light-controlled junction this step entered, kTlNone when it
  // entered none (light_at_junction_entry, world/ground_truth.hpp).
  int entered_light = kTlNone;
  // ego.lateral = "free": this step began driving against its lane's direction / crossed the
  // border of its lane (onsets, world/lane_contact.hpp).
  bool wrong_way = false;
  bool lane_invasion = false;
};

struct WorldCounters {
  int red_light_violations = 0;
  double distance = 0;  // m driven
  // ego.lateral = "free": onsets of wrong-way driving and lane invasions, and the sum of the
  // absolute lateral error to the lane centre over `lateral_samples` steps on a lane.
  int wrong_way = 0;
  int lane_invasions = 0;
  int lane_changes = 0;  // moves of the SUMO stand-in to a neighbouring lane of its edge
  double lateral_error_sum = 0;
  long lateral_samples = 0;
};

// The front camera's signal head of a signalised approach lane: its pole (0.6 m right of the
// lane's end), the way its lamps face (against the lane's direction), and the connection whose
// state it shows (the straight one where there is one, else the first by id).
struct SignalHead {
  std::string approach;
  Vec2 pole;
  double facing = 0;
  const ViaInfo* via = nullptr;
};
// Every signalised approach lane's head, sorted by lane id.
std::vector<SignalHead> find_signal_heads(const RoadNetwork& net);

class World {
 public:
  // Starts SUMO on the configured network and reads its RoadNetwork.
  explicit World(const WorldConfig& config);
  // Is a World alive in this process (libsumo runs one simulation per process)?
  static bool alive();
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

  // The sensor's frame of the current state (sense.view): frame_format().bytes() bytes, C
  // planes of H*W (the BEV's channels 0/255, or the camera's RGB). render_from: the same seen
  // from another ego pose (collect.augment's shifted and rotated views).
  void render(uint8_t* out) const;
  void render_from(const Pose2& seen, uint8_t* out) const;
  const FrameFormat& frame_format() const { return format_; }
  bool camera_view() const { return camera_ != nullptr; }
  // The camera's appearance set of this episode (sense.camera.weather: a set, or one drawn
  // from a pool by the task's traffic seed at reset); empty with the BEV.
  std::string weather() const { return camera_ ? camera_->weather().name : std::string(); }
  void render_packed(uint8_t* out) const;  // the BEV as H*W bytes of channel bits (bev only)
  BevScene scene() const;
  // What the front camera sees now (sense/camera.hpp): the road users in view with their
  // colours and brake lights (a car decelerating at over 1 m/s^2), and a signal head at every
  // signalised stop line within `radius` m of the ego, showing its straight link's state (the
  // ego's own approach: the ego's next link, what the BEV shows).
  CameraScene camera_scene(double radius = 150.0) const;

  const EgoState& ego() const { return ego_; }
  const GroundTruth& truth() const { return truth_; }
  int command() const { return command_; }
  const Task& task() const { return task_; }
  const WorldCounters& counters() const { return counters_; }
  const std::vector<Actor>& actors() const { return actors_; }
  const RoadNetwork& network() const { return *net_; }
  const RoadMap& map() const { return net_->map; }
  const WorldConfig& settings() const { return config_; }
  const EgoModel& ego_model() const { return ego_model_; }
  bool free_lateral() const { return free_; }
  double steer_angle() const { return steer_angle_; }  // rad of road wheel (free)
  // Where the ego's footprint lies among the lanes (free; in route mode: on its lane).
  const RoadContact& road_contact() const { return contact_; }
  const BevRenderer& renderer() const { return *renderer_; }
  const std::string& network_path() const { return net_->path; }
  double time() const { return ego_.time; }
  // Path lanes of the current route from the ego on (ids), for the route layer and tests.
  const std::vector<std::string>& route_lanes() const { return route_lanes_; }
  // The point of the ego's path `s` metres ahead of its front bumper (network frame), or its
  // last point when the path known this step is shorter.
  Vec2 path_point(double s) const { return path_.point(s, ego_.pose.pos); }
  // Metres ahead to where a lane change the route needs must begin while traffic on the lane
  // it joins keeps it from beginning now (the expert waits there); 1e300 when none is held.
  double lane_change_hold() const { return path_.hold; }

  // Test hooks: place a stopped vehicle on a lane position (scripted scenarios), and read
  // the per-step collision and red-light state.
  std::string add_scripted_vehicle(const std::string& lane_id, double pos, double speed);
  void set_vehicle_speed(const std::string& id, double speed);
  // A scripted pedestrian: added on an edge's sidewalk (in the world after the next step), then
  // put anywhere, the road included, by place_pedestrian for the following step (SUMO does not
  // keep a person off its network: place it before every step it is to stand there).
  std::string add_scripted_pedestrian(const std::string& edge, double pos);
  void place_pedestrian(const std::string& id, Vec2 at);

 private:
  struct Sumo;  // what only libsumo knows of this session (world.cpp)

  std::vector<std::string> sumo_args(uint64_t seed) const;
  void spawn_background();
  void top_up_background();
  bool add_background_car(const std::string& id);
  void insert_ego();
  // Free steering: moves the SUMO stand-in to the lane of its edge that the bicycle's centre
  // is on, when that is another lane (a lane change), its front beside the bicycle's `front`.
  // Returns whether it moved.
  bool follow_lane_change(Vec2 front);
  // Is the lane `to` free of cars around lane position `pos`, so that the ego may change onto
  // it now?
  bool lane_change_clear(const LaneGeom& to, double pos) const;
  // red_light: runs the simulation until the light of the ego's first link turns red.
  void wait_for_red_onset();
  void advance();  // one SUMO step plus the periodic background refill
  void refresh();  // reads SUMO state, recomputes actors, path, truth, command
  char link_state(const ViaInfo& vi) const;  // current state of the link (light or fixed)
  // Must a car about to use this internal lane wait (pedestrians on or heading for a foe
  // crossing, cars in the conflict area, priority cars arriving when the ego's link is minor)?
  bool junction_lane_blocked(const std::string& lane, bool minor);
  StepResult check_events(bool ego_present);
  std::vector<std::string> route_lane_sequence() const;
  Box ego_box() const {
    return {ego_.pose.pos, ego_.pose.heading, config_.ego.length, config_.ego.width};
  }

  WorldConfig config_;
  EgoModel ego_model_;
  bool free_ = false;
  std::unique_ptr<LaneGrid> grid_;
  double steer_angle_ = 0;
  bool free_pose_valid_ = false;  // free: ego_.pose and speed are ours, not read from SUMO
  Pose2 free_pose_;
  double free_speed_ = 0;
  RoadContact contact_;
  std::shared_ptr<const RoadNetwork> net_;
  std::unique_ptr<BevRenderer> renderer_;
  // sense.view = "camera": the front camera (GL state changes as it draws, hence mutable).
  mutable std::unique_ptr<CameraRenderer> camera_;
  FrameFormat format_;
  std::unique_ptr<Sumo> sumo_;

  Task task_;
  LanePlan plan_;  // lane plan of the current task
  std::unique_ptr<class Rng> traffic_rng_;
  int target_cars_ = 0, target_peds_ = 0, next_actor_id_ = 0, scripted_ = 0;
  double ego_entry_time_ = 0;
  long steps_since_load_ = 0;
  EgoState ego_;
  GroundTruth truth_;
  int command_ = kFollow;
  WorldCounters counters_;
  std::vector<Actor> actors_;
  std::unordered_map<std::string, double> actor_speed_;  // last step's speeds (Actor::accel)
  std::vector<SignalHead> signal_heads_;
  RoutePath path_;
  std::vector<std::string> route_lanes_;
  char prev_link_state_ = 0;
  double prev_link_distance_ = 1e9;
  bool ego_present_ = false;
  bool leader_held_ = false;  // leader scenario: the leader still waits
  Outcome outcome_ = Outcome::Running;
};

}  // namespace cd
