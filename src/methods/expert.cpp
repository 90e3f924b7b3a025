// expert: the privileged autopilot the data was collected with (agent only).
#include "agents/agent.hpp"
#include "core/error.hpp"
#include "expert/autopilot.hpp"
#include "world/world.hpp"

namespace cd {

namespace {

// The autopilot reads the World it drives in (privileged state), given when it is built; a
// null world makes an expert that can be named and checked but not driven.
class ExpertAgent : public Agent {
 public:
  ExpertAgent(const Settings& s, const World* world) : expert_(s.expert), world_(world) {}
  std::string name() const override { return "expert"; }
  bool uses_frames() const override { return false; }
  bool steers() const override { return true; }
  Control act(const Observation&) override {
    if (!world_) throw Error("the expert agent was built without a World to drive in");
    return expert_.act(*world_);
  }

 private:
  Autopilot expert_;
  const World* world_;
};

}  // namespace

std::unique_ptr<Agent> load_expert_agent(const std::string&, const std::string&,
                                         const Settings& settings, const World* world) {
  return std::make_unique<ExpertAgent>(settings, world);
}

}  // namespace cd
