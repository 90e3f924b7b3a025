// expert: the privileged autopilot the data was collected with (agent only).
#include "agents/agent.hpp"
#include "expert/autopilot.hpp"
#include "world/world.hpp"

namespace cd {

namespace {

class ExpertAgent : public Agent {
 public:
  explicit ExpertAgent(const Settings& s) : expert_(s.expert) {}
  std::string name() const override { return "expert"; }
  bool uses_frames() const override { return false; }
  Control act(const Observation&, const World& world) override { return expert_.act(world); }

 private:
  Autopilot expert_;
};

}  // namespace

std::unique_ptr<Agent> load_expert_agent(const std::string&, const std::string&,
                                         const Settings& settings) {
  return std::make_unique<ExpertAgent>(settings);
}

}  // namespace cd
