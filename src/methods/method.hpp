#pragma once
// The methods of SPEC section 3, each a name usable in `causaldrive train --method NAME` and
// as an agent. One table (methods/registry.cpp) says, per method, what it trains, how its agent
// is loaded, how it adjusts the settings and its help line; each method is one file of this
// folder, named after it.
#include <memory>
#include <string>
#include <vector>

#include "agents/agent.hpp"
#include "app/settings.hpp"
#include "train/request.hpp"

namespace cd {

class World;
struct FrameFormat;

using TrainFn = TrainSummary (*)(const Settings& settings, const TrainRequest& request);
// `run_dir` is the method's training output (empty for methods without training); `world` the
// World the agent will drive in (only the privileged expert reads it; may be null when the
// agent is only checked).
using AgentFn = std::unique_ptr<Agent> (*)(const std::string& method, const std::string& run_dir,
                                           const Settings& settings, const World* world);
using AdjustFn = void (*)(Settings& settings);

struct MethodSpec {
  const char* name;
  const char* help;         // one line: what it is
  TrainFn train;            // nullptr: an agent without training (expert, cs)
  AgentFn agent;
  AdjustFn adjust;          // nullptr: it trains with the settings as given
  bool reuses_runs;         // takes --init and --vae (the cim family)
};

// Every method of the table, in its order.
const std::vector<MethodSpec>& methods();

// The spec of `name`; ConfigError listing the known names otherwise.
const MethodSpec& find_method(const std::string& name);
// Names of the trainable methods, in table order.
std::vector<std::string> trainable_methods();

// Throws ConfigError: "an agent without training" for the agent-only names (expert, cs), the
// list of trainable names otherwise.
void check_train_method(const std::string& method);

// The settings a method really trains with (bc-so sees one frame, cim-entangled's VAE has
// beta 1, dim is a single model).
Settings effective_settings(const std::string& method, Settings settings);

// Trains request.method (checked first).
TrainSummary train_method(const Settings& settings, const TrainRequest& request);

// Agents by name: expert, cs, and the learned methods (which need their run folder), to drive
// in `world` (the expert needs it to act; null: an agent that is only checked).
// Throws ConfigError for an unknown name or a folder of another method, and, given a world, for
// a run whose frames (its record's "input") are not the world's: another view (sense.view) or
// size. (Without a world the caller supplies the observations; eval checks the view first.)
std::unique_ptr<Agent> make_agent(const std::string& name, const std::string& run_dir,
                                  const Settings& settings, const World* world = nullptr);
// The last check of make_agent: ConfigError when `run_dir` was trained on frames of another
// view or size than `world` renders; nothing when its record names no input.
void require_trained_view(const std::string& agent, const std::string& run_dir,
                          const FrameFormat& world);

}  // namespace cd
