#include <cmath>

#include "agents/agent.hpp"
#include "agents/learned_agents.hpp"
#include "agents/policy_agent.hpp"
#include "control/pid.hpp"
#include "core/error.hpp"
#include "expert/autopilot.hpp"
#include "world/world.hpp"

namespace cd {

namespace {

// The privileged autopilot (what the data was collected with).
class ExpertAgent : public Agent {
 public:
  explicit ExpertAgent(const Settings& s) : expert_(s.expert) {}
  std::string name() const override { return "expert"; }
  bool uses_frames() const override { return false; }
  Control act(const Observation&, const World& world) override { return expert_.act(world); }

 private:
  Autopilot expert_;
};

// Constant speed along the route, blind to everything (seed 000's CS): the collision upper
// bound of the benchmark.
class ConstantSpeedAgent : public Agent {
 public:
  explicit ConstantSpeedAgent(const Settings& s)
      : speed_(s.eval.cs_speed), pid_(s.control, EgoModel(s.ego), s.world.dt) {}
  std::string name() const override { return "cs"; }
  bool uses_frames() const override { return false; }
  void begin_episode() override { pid_.reset(); }
  Control act(const Observation& obs, const World&) override {
    return pid_.control(speed_, obs.speed);
  }
  double last_target_speed() const override { return speed_; }

 private:
  double speed_;
  SpeedPid pid_;
};

}  // namespace

const std::vector<AgentKind>& agent_kinds() {
  static const std::vector<AgentKind> kinds = {
      {"expert", false}, {"cs", false},  {"bc-so", true},   {"bc-oh", true},
      {"dim", true},     {"rip", true},  {"cim", true},     {"cim-mlp", true},
      {"cim-entangled", true}};
  return kinds;
}

std::unique_ptr<Agent> make_agent(const std::string& name, const std::string& checkpoint,
                                  const Settings& settings) {
  if (name == "expert") return std::make_unique<ExpertAgent>(settings);
  if (name == "cs") return std::make_unique<ConstantSpeedAgent>(settings);
  for (const AgentKind& k : agent_kinds()) {
    if (k.name != name || !k.learned) continue;
    if (checkpoint.empty())
      throw ConfigError("agent '" + name + "' needs --checkpoint DIR (the output of "
                        "`causaldrive train --method " + name + "`)");
    if (name == "dim" || name == "rip") return load_dim_agent(name, checkpoint, settings);
    if (name.rfind("cim", 0) == 0) return load_cim_agent(name, checkpoint, settings);
    return load_policy_agent(name, checkpoint, settings);
  }
  std::string known;
  for (const AgentKind& k : agent_kinds()) known += (known.empty() ? "" : ", ") + k.name;
  throw ConfigError("unknown agent '" + name + "' (known: " + known + ")");
}

}  // namespace cd
