#include "learn/methods.hpp"

#include <algorithm>

#include "core/error.hpp"

namespace cd {

namespace {

std::string join(const std::vector<std::string>& names) {
  std::string s;
  for (const auto& n : names) s += (s.empty() ? "" : ", ") + n;
  return s;
}

bool contains(const std::vector<std::string>& v, const std::string& x) {
  return std::find(v.begin(), v.end(), x) != v.end();
}

}  // namespace

const std::vector<std::string>& available_train_methods() {
  static const std::vector<std::string> names = {"bc-so", "bc-oh", "dim", "rip", "cim",
                                                  "cim-mlp", "cim-entangled"};
  return names;
}

const std::vector<std::string>& planned_train_methods() {
  static const std::vector<std::string> names = {
      "residual", "fca", "keyframe", "hd", "dagger"};
  return names;
}

void check_train_method(const std::string& method) {
  const auto& available = available_train_methods();
  if (contains(available, method)) return;
  if (contains(planned_train_methods(), method))
    throw ConfigError("method '" + method + "' is not available in this version (available: " +
                      join(available) + ")");
  if (method == "expert" || method == "cs")
    throw ConfigError("method '" + method + "' is an agent without training (trainable: " +
                      join(available) + ")");
  std::vector<std::string> known = available;
  known.insert(known.end(), planned_train_methods().begin(), planned_train_methods().end());
  throw ConfigError("unknown method '" + method + "' (known: " + join(known) +
                    "; available in this version: " + join(available) + ")");
}

Settings effective_settings(const std::string& method, Settings s) {
  if (method == "bc-so") {
    s.model.history = 1;
    s.model.history_stride = 1;
  }
  if (method == "cim-entangled") s.vae.beta = 1.0;  // the plain VAE of the ablation
  if (method == "dim") s.dim.ensemble = 1;
  return s;
}

}  // namespace cd
