#pragma once
// Files of the repo compiled into the binary (town specs, the default config), keyed by
// their path relative to the repo root, e.g. "towns/town-a.toml".
#include <map>
#include <string>

namespace cd {
const std::map<std::string, std::string>& embedded_files();
}
