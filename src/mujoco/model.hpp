#pragma once
// MuJoCo models: the immutable mjModel, loaded once per file and shared by every Env of the
// process (MuJoCo's own split: one model, one mjData per simulation).
#include <memory>
#include <string>

// MuJoCo's model and data, declared as mujoco.h does: only the files that call MuJoCo include it
// (a build without MuJoCo compiles everything else).
struct mjModel_;
typedef struct mjModel_ mjModel;
struct mjData_;
typedef struct mjData_ mjData;

namespace cd::mj {

using ModelPtr = std::shared_ptr<const mjModel>;

// The folder holding the MJCF files: `override_dir` when set, else $CAUSALDRIVE_MUJOCO_ASSETS,
// else the source tree's assets/mujoco.
std::string assets_dir(const std::string& override_dir = "");

// Loads (or returns the cached) model of an MJCF file. A missing file is a ConfigError, an
// invalid one a SimError, each one line naming the file.
ModelPtr load_model(const std::string& path);

// Routes MuJoCo's fatal errors into cd::SimError and keeps its warnings off stdout and out of
// MUJOCO_LOG.TXT. Called by load_model; idempotent.
void install_error_handlers();

}  // namespace cd::mj
