#pragma once
// Loaders of the seed-000 agents (cim family, dim, rip), each from its run folder.
#include <memory>
#include <string>

#include "agents/agent.hpp"

namespace cd {

std::unique_ptr<Agent> load_cim_agent(const std::string& method, const std::string& dir,
                                      const Settings& settings);
std::unique_ptr<Agent> load_dim_agent(const std::string& method, const std::string& dir,
                                      const Settings& settings);

}  // namespace cd
