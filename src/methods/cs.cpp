// cs (seed 000): constant speed along the route, blind to everything: the collision upper
// bound of the benchmark (agent only). A free-steering ego (ego.lateral = "free") follows the
// route with the expert's path tracker.
#include "agents/agent.hpp"
#include "control/pid.hpp"
#include "expert/autopilot.hpp"
#include "world/world.hpp"

namespace cd {

namespace {

class ConstantSpeedAgent : public Agent {
 public:
  ConstantSpeedAgent(const Settings& s, const World* world)
      : speed_(s.eval.cs_speed),
        pid_(s.control, EgoModel(s.ego), s.world.dt),
        world_(world),
        free_(s.ego.lateral == "free") {}
  std::string name() const override { return "cs"; }
  bool uses_frames() const override { return false; }
  void begin_episode() override { pid_.reset(); }
  Control act(const Observation& obs) override {
    Control c = pid_.control(speed_, obs.speed);
    if (free_ && world_) c.steer = steer_towards_path(*world_);
    return c;
  }
  double last_target_speed() const override { return speed_; }
  bool steers() const override { return true; }  // with the expert's path tracker
  bool steers_from_world() const override { return free_; }

 private:
  double speed_;
  SpeedPid pid_;
  const World* world_;  // the route's geometry for its path tracker (free lateral control)
  bool free_;           // ego.lateral = "free": the agent steers
};

}  // namespace

std::unique_ptr<Agent> load_cs_agent(const std::string&, const std::string&,
                                     const Settings& settings, const World* world) {
  return std::make_unique<ConstantSpeedAgent>(settings, world);
}

}  // namespace cd
