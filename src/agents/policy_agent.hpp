#pragma once
// Learned agents (bc-so, bc-oh): a trained network from a checkpoint folder, in closed loop.
#include <memory>
#include <string>

#include "agents/agent.hpp"

namespace cd {

// Loads the checkpoint written by `causaldrive train --method <method>` in `dir`. Throws
// DataError for a missing or damaged checkpoint, ConfigError when it holds another method.
// Inference runs on the CPU with settings.train.threads threads unless the checkpoint's
// config asks for more.
std::unique_ptr<Agent> load_policy_agent(const std::string& method, const std::string& dir,
                                         const Settings& settings);

}  // namespace cd
