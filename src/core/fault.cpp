#include "core/fault.hpp"

#include <signal.h>

#include <algorithm>
#include <cctype>
#include <cstdlib>
#include <filesystem>
#include <fstream>

#include "core/error.hpp"

namespace cd {

namespace {

bool all_digits(const std::string& s) {
  if (s.empty() || s.size() > 15) return false;
  for (char c : s)
    if (!std::isdigit(static_cast<unsigned char>(c))) return false;
  return true;
}

}  // namespace

CrashSpec parse_crash_spec(const std::string& text) {
  std::string rest = text;
  CrashSpec spec;
  const std::string always = ":always";
  if (rest.size() > always.size() &&
      rest.compare(rest.size() - always.size(), always.size(), always) == 0) {
    spec.always = true;
    rest.resize(rest.size() - always.size());
  }
  const auto colon = rest.rfind(':');
  spec.site = colon == std::string::npos ? "eval" : rest.substr(0, colon);
  const std::string index = colon == std::string::npos ? rest : rest.substr(colon + 1);
  if (spec.site.empty() || !all_digits(index))
    throw ConfigError(std::string(kInjectCrashEnv) + "=" + text +
                      ": expected <site>:<index>[:always]");
  spec.index = std::atol(index.c_str());
  return spec;
}

void inject_crash(const std::string& site, long index, const std::string& marker_dir,
                  CrashScope scope) {
  // The test hook's variable, documented in core/fault.hpp.
  const char* value = std::getenv(kInjectCrashEnv);
  if (!value || !*value) return;
  // Several specs, comma-separated, kill at each of their points.
  CrashSpec spec;
  bool hit = false;
  std::string list = value;
  for (size_t start = 0; start <= list.size() && !hit;) {
    const size_t comma = std::min(list.find(',', start), list.size());
    spec = parse_crash_spec(list.substr(start, comma - start));
    hit = spec.site == site && spec.index == index;
    start = comma + 1;
  }
  if (!hit) return;
  if (!spec.always && !marker_dir.empty()) {
    const std::string marker =
        marker_dir + "/.crash-injected-" + site + "-" + std::to_string(index);
    std::error_code ec;
    if (std::filesystem::exists(marker, ec)) return;
    std::ofstream(marker) << "1\n";
  }
  if (scope == CrashScope::ProcessGroup) ::kill(0, SIGKILL);
  ::raise(SIGKILL);
}

}  // namespace cd
