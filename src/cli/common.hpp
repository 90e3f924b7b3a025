#pragma once
#include <string>

#include "app/settings.hpp"
#include "train/request.hpp"

namespace cd::cli {

// The settings of a config file, or the built-in defaults (= configs/quickstart.toml).
inline Settings settings_from(const std::string& config_path) {
  return config_path.empty() ? Settings{} : load_settings(config_path);
}

// The lines `causaldrive train` prints at the end of a run.
void print_train_summary(const TrainSummary& s);

}  // namespace cd::cli
