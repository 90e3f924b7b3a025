#pragma once
// What drives the ego in closed loop: the expert, the constant-speed baseline, or a learned
// policy. The benchmark runner owns the observation history and hands each agent the frames
// it asked for (history() frames, history_stride() steps apart, oldest first), always real
// frames of the episode (SPEC section 1), never one frame repeated.
#include <cmath>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "app/settings.hpp"
#include "world/ego_model.hpp"

namespace cd {

class World;  // what the privileged expert drives in (methods/expert.cpp)

struct Observation {
  std::vector<const uint8_t*> frames;  // oldest first, last = current; each C*H*W bytes, 0/255
  int channels = 0, height = 0, width = 0;
  const char* view = "bev";  // what the frames are (sense.view): "bev" or "camera"
  double speed = 0;  // m/s measured; learned agents zero it unless their config says otherwise
  int command = 0;   // cd::Command at the next junction
  // Navigation goal for planners (dim, rip): the route point goal_distance() metres ahead of
  // the ego's front, in the ego frame (x forward, y left, m, from the ego's centre). Only
  // filled for agents whose goal_distance() > 0; route geometry, not a cause.
  double goal_x = 0, goal_y = 0;
  // Ego odometry: position (m, network frame) and heading (rad, 0 = east, CCW). Planners keep
  // their own past positions from it (the ego stood still, braked, before the first act()).
  double x = 0, y = 0, heading = 0;
};

class Agent {
 public:
  virtual ~Agent() = default;
  virtual std::string name() const = 0;
  virtual int history() const { return 1; }         // frames in Observation::frames
  virtual int history_stride() const { return 1; }  // simulation steps between them
  virtual bool uses_frames() const { return true; }  // false: the runner renders nothing
  virtual double goal_distance() const { return 0; }  // > 0: fill Observation::goal_x/y
  // Does act() steer (Control::steer)? An agent that does not cannot drive a free-steering ego
  // (ego.lateral = "free"); make_agent refuses it there.
  virtual bool steers() const { return false; }
  // Does act() steer from the route's geometry of the World it was built with (cs, and cim
  // without eval.cim_path, steering a free ego with the expert's path tracker)? Such an agent
  // cannot act from observations alone (Python's causaldrive.Agent refuses it).
  virtual bool steers_from_world() const { return false; }
  virtual void begin_episode() {}
  // The control for this step, from the observation alone (the expert was given its World
  // when it was built: it is the only privileged agent).
  virtual Control act(const Observation& obs) = 0;
  // The target speed behind the last act() (NaN when the agent outputs throttle/brake).
  virtual double last_target_speed() const { return std::nan(""); }
  // Figures of the episode since begin_episode() that the agent wants in its episode record
  // (results.json "agent"; numbers are averaged over episodes into the summary's "agent").
  virtual nlohmann::json episode_figures() const { return nlohmann::json::object(); }
};

// "CxHxW".
std::string frame_shape(int channels, int height, int width);

// What every learned agent checks of an observation first: frames of the shape it was trained
// on (ConfigError naming both shapes and the fix) and `history` of them (Error).
void check_observation(const std::string& agent, const Observation& obs, int channels, int height,
                       int width, int history);

// The agents by name are in methods/method.hpp (make_agent).

}  // namespace cd
