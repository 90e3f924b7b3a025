#include "agents/learned_agents.hpp"
#include "core/error.hpp"

namespace cd {

std::unique_ptr<Agent> load_cim_agent(const std::string&, const std::string&, const Settings&) {
  throw Error("load_cim_agent: being implemented");
}

}  // namespace cd
