// The dim and rip agents: every dim.replan_steps steps, plan a trajectory by maximising the (aggregated)
// likelihood of the run's DIM members plus the goal term (learn/dim_run.hpp), and drive at the
// speed the plan implies with the shared speed PID. The ego follows its route lanes exactly,
// so the plan's speed is all that reaches the vehicle. The measured speed is not an input
// (POMDP): the model sees the current frame and the past positions from odometry.
#include <cmath>
#include <deque>

#include "agents/learned_agents.hpp"
#include "control/pid.hpp"
#include "core/error.hpp"
#include "learn/dim_run.hpp"
#include "learn/policy_runner.hpp"
#include "sense/bev.hpp"

namespace cd {

namespace {

struct OdoPose {
  double x, y, heading;
};

class DimAgent : public Agent {
 public:
  DimAgent(const std::string& method, const std::string& dir, const Settings& s)
      : method_(method),
        planner_(dir, method),
        pid_(s.control, EgoModel(s.ego), s.world.dt),
        planning_(s.dim) {
    planner_.set_planning(planning_);
    // Refused here, in the process that loads the agent, rather than at the first act() of
    // an episode worker.
    const InputFormat& in = planner_.run().input;
    const int channels = static_cast<int>(kBevChannelCount);
    if (in.channels != channels || in.height != s.bev.height || in.width != s.bev.width)
      throw ConfigError("agent '" + method_ + "' was trained on " +
                        shape(in.channels, in.height, in.width) + " BEV frames but the [bev] " +
                        "settings give " + shape(channels, s.bev.height, s.bev.width) +
                        ": use the [bev] settings of its training data");
  }

  std::string name() const override { return method_; }
  int history() const override { return 1; }
  // Planning settings come from the evaluation's config ([dim] plan_*, goal_*, replan_steps,
  // aggregation), the network's from the run.
  double goal_distance() const override { return planning_.goal_distance; }

  void begin_episode() override {
    pid_.reset();
    poses_.clear();
    steps_ = 0;
    target_ = std::nan("");
  }

  Control act(const Observation& obs, const World&) override {
    const InputFormat& in = planner_.run().input;
    if (obs.channels != in.channels || obs.height != in.height || obs.width != in.width)
      throw ConfigError("agent '" + method_ + "' was trained on " +
                        shape(in.channels, in.height, in.width) + " BEV frames but is given " +
                        shape(obs.channels, obs.height, obs.width) +
                        ": use the [bev] settings of its training data");
    if (obs.frames.size() != 1)
      throw Error("agent '" + method_ + "' needs 1 frame per observation, got " +
                  std::to_string(obs.frames.size()));
    const DimSettings& d = planner_.run().dim;
    // Odometry of every step, newest last; before the first act() the ego stood still, so a
    // position older than what was seen is the first one seen.
    const size_t keep = static_cast<size_t>(d.past) * d.waypoint_step + 1;
    poses_.push_back({obs.x, obs.y, obs.heading});
    if (poses_.size() > keep) poses_.pop_front();
    const OdoPose& now = poses_.back();
    std::vector<double> past(2 * d.past);
    for (int k = 0; k < d.past; ++k) {
      const long back = static_cast<long>(k + 1) * d.waypoint_step;
      const long i = std::max(0L, static_cast<long>(poses_.size()) - 1 - back);
      to_ego_frame(now.x, now.y, now.heading, poses_[i].x, poses_[i].y, past[2 * k],
                   past[2 * k + 1]);
    }
    // Replanning every replan_steps steps (the plan covers horizon * waypoint_step steps); the
    // speed of the last plan is tracked in between.
    if (steps_++ % planning_.replan_steps == 0)
      target_ = planner_.plan(obs.frames.back(), past, obs.goal_x, obs.goal_y).target_speed;
    return pid_.control(target_, obs.speed);
  }

  double last_target_speed() const override { return target_; }

 private:
  static std::string shape(int c, int h, int w) {
    return std::to_string(c) + "x" + std::to_string(h) + "x" + std::to_string(w);
  }
  std::string method_;
  DimPlanner planner_;
  SpeedPid pid_;
  DimSettings planning_;
  std::deque<OdoPose> poses_;
  long steps_ = 0;
  double target_ = std::nan("");
};

}  // namespace

std::unique_ptr<Agent> load_dim_agent(const std::string& method, const std::string& dir,
                                      const Settings& settings) {
  if (method != "dim" && method != "rip")
    throw ConfigError("load_dim_agent: '" + method + "' is not dim or rip");
  set_torch_threads(1);
  return std::make_unique<DimAgent>(method, dir, settings);
}

}  // namespace cd
