#include "agents/learned_agents.hpp"
#include "core/error.hpp"

namespace cd {

std::unique_ptr<Agent> load_dim_agent(const std::string&, const std::string&, const Settings&) {
  throw Error("load_dim_agent: being implemented");
}

}  // namespace cd
