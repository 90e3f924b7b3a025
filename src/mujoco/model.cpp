#include "mujoco/model.hpp"

#include <mujoco/mujoco.h>

#include <cstdlib>
#include <filesystem>
#include <map>
#include <mutex>

#include "core/error.hpp"

namespace cd::mj {

namespace {

// MuJoCo calls this instead of exiting. libmujoco is C built with unwind tables (x86-64
// default), so the exception reaches our frames; MuJoCo raises errors only on states it cannot
// continue from (arena overflow), never for a model we ship.
void throw_error(const char* msg) { throw SimError(std::string("MuJoCo: ") + msg); }

// Instability warnings (bad qacc) make mj_step reset the data itself, as in Gym; nothing to do.
void ignore_warning(const char*) {}

}  // namespace

void install_error_handlers() {
  static std::once_flag once;
  std::call_once(once, [] {
    mju_user_error = throw_error;
    mju_user_warning = ignore_warning;
  });
}

std::string assets_dir(const std::string& override_dir) {
  if (!override_dir.empty()) return override_dir;
  if (const char* env = std::getenv("CAUSALDRIVE_MUJOCO_ASSETS"); env != nullptr && *env != '\0')
    return env;
  return std::string(CD_SOURCE_DIR) + "/assets/mujoco";
}

ModelPtr load_model(const std::string& path) {
  install_error_handlers();
  static std::mutex mutex;
  static std::map<std::string, ModelPtr> cache;
  std::lock_guard<std::mutex> lock(mutex);
  if (auto it = cache.find(path); it != cache.end()) return it->second;
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) {
    throw ConfigError("MuJoCo model file " + path +
                      " not found (set CAUSALDRIVE_MUJOCO_ASSETS to the folder of the MJCF files)");
  }
  char error[1000] = "";
  mjModel* m = mj_loadXML(path.c_str(), nullptr, error, sizeof error);
  if (m == nullptr) {
    std::string reason(error);
    for (char& c : reason)
      if (c == '\n' || c == '\r') c = ' ';  // one line
    throw SimError("cannot load MuJoCo model " + path + ": " + reason);
  }
  ModelPtr model(m, [](const mjModel* p) { mj_deleteModel(const_cast<mjModel*>(p)); });
  cache.emplace(path, model);
  return model;
}

}  // namespace cd::mj
