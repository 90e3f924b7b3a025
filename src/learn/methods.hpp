#pragma once
// Names accepted by `causaldrive train --method` (SPEC section 3) and what each trains.
#include <string>
#include <vector>

#include "app/settings.hpp"

namespace cd {

// Trainable in this version: bc-so, bc-oh, dim, rip, cim, cim-mlp, cim-entangled.
const std::vector<std::string>& available_train_methods();
// In SPEC section 3 but not implemented yet (dim, rip, cim, ...).
const std::vector<std::string>& planned_train_methods();

// Throws ConfigError: "not available in this version" for a planned method, "nothing to
// train" for the agent-only names (expert, cs), the list of known names otherwise.
void check_train_method(const std::string& method);

// The settings a method really trains with: bc-so sees one frame (history 1, stride 1),
// cim-entangled's VAE has beta 1, dim is a single model (dim.ensemble 1).
Settings effective_settings(const std::string& method, Settings settings);

}  // namespace cd
