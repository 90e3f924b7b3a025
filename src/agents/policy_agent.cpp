#include "agents/policy_agent.hpp"

#include <cmath>

#include "control/pid.hpp"
#include "core/error.hpp"
#include "learn/policy_runner.hpp"

namespace cd {

namespace {

class PolicyAgent : public Agent {
 public:
  PolicyAgent(const std::string& method, const std::string& dir, const Settings& s)
      : method_(method), runner_(dir, method), pid_(s.control, EgoModel(s.ego), s.world.dt) {}

  std::string name() const override { return method_; }
  int history() const override { return runner_.history(); }
  int history_stride() const override { return runner_.stride(); }
  void begin_episode() override {
    pid_.reset();
    target_ = std::nan("");
  }

  Control act(const Observation& obs, const World&) override {
    const InputFormat& in = runner_.checkpoint().input;
    if (obs.channels != in.channels || obs.height != in.height || obs.width != in.width)
      throw ConfigError("agent '" + method_ + "' was trained on " + shape(in.channels, in.height,
                        in.width) + " BEV frames but is given " +
                        shape(obs.channels, obs.height, obs.width) + ": use the [bev] settings "
                        "of its training data");
    if (static_cast<int>(obs.frames.size()) != in.history)
      throw Error("agent '" + method_ + "' needs " + std::to_string(in.history) +
                  " frames per observation, got " + std::to_string(obs.frames.size()));
    PolicyStep step = runner_.run(obs.frames.data(), obs.speed, obs.command);
    if (runner_.target_speed_head()) {
      target_ = step.target_speed;
      return pid_.control(target_, obs.speed);
    }
    return Control{step.throttle, step.brake};
  }

  double last_target_speed() const override { return target_; }

 private:
  static std::string shape(int c, int h, int w) {
    return std::to_string(c) + "x" + std::to_string(h) + "x" + std::to_string(w);
  }
  std::string method_;
  PolicyRunner runner_;
  SpeedPid pid_;
  double target_ = std::nan("");
};

}  // namespace

std::unique_ptr<Agent> load_policy_agent(const std::string& method, const std::string& dir,
                                         const Settings& settings) {
  set_torch_threads(1);
  return std::make_unique<PolicyAgent>(method, dir, settings);
}

}  // namespace cd
