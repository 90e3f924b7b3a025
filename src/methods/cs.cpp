// cs (seed 000): constant speed along the route, blind to everything: the collision upper
// bound of the benchmark (agent only).
#include "agents/agent.hpp"
#include "control/pid.hpp"

namespace cd {

namespace {

class ConstantSpeedAgent : public Agent {
 public:
  explicit ConstantSpeedAgent(const Settings& s)
      : speed_(s.eval.cs_speed), pid_(s.control, EgoModel(s.ego), s.world.dt) {}
  std::string name() const override { return "cs"; }
  bool uses_frames() const override { return false; }
  void begin_episode() override { pid_.reset(); }
  Control act(const Observation& obs) override {
    return pid_.control(speed_, obs.speed);
  }
  double last_target_speed() const override { return speed_; }

 private:
  double speed_;
  SpeedPid pid_;
};

}  // namespace

std::unique_ptr<Agent> load_cs_agent(const std::string&, const std::string&,
                                     const Settings& settings, const World*) {
  return std::make_unique<ConstantSpeedAgent>(settings);
}

}  // namespace cd
