#pragma once
// Learned agents (bc-so, bc-oh): a trained network from a checkpoint folder, in closed loop.
#include <memory>
#include <string>

#include "agents/agent.hpp"

namespace cd {

// Loads the checkpoint written by `causaldrive train --method <method>` in `dir` (its best.pt,
// built from the checkpoint's own model settings). Throws DataError for a missing or damaged
// checkpoint, ConfigError when it holds another method. Inference runs on the CPU with one
// torch thread (the benchmark runs one worker process per core). history() and
// history_stride() are the checkpoint's; the speed in the observation is zeroed unless the
// model was trained with model.speed_input. A target_speed head is tracked by SpeedPid with
// settings.control.
std::unique_ptr<Agent> load_policy_agent(const std::string& method, const std::string& dir,
                                         const Settings& settings);

}  // namespace cd
