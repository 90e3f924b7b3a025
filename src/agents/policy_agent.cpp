// PLACEHOLDER (owner: learn) — replaced by the torch implementation.
#include "agents/policy_agent.hpp"
#include "core/error.hpp"
namespace cd {
std::unique_ptr<Agent> load_policy_agent(const std::string& method, const std::string&,
                                         const Settings&) {
  throw ConfigError("agent '" + method + "' is not available yet");
}
}  // namespace cd
