#include "world/town.hpp"

#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <cstring>
#include <sstream>

#include "core/atomic_file.hpp"
#include "core/config.hpp"
#include "core/embedded.hpp"
#include "core/error.hpp"
#include "core/process.hpp"

namespace fs = std::filesystem;

namespace cd {

namespace {

constexpr const char* kTownPrefix = "towns/";
constexpr const char* kTownSuffix = ".toml";
// netgenerate's own random choices (rand networks) are fixed by the spec; this seed only
// covers options that the spec leaves random.
constexpr const char* kNetSeed = "42";

uint64_t fnv1a(const std::string& s) {
  uint64_t h = 1469598103934665603ull;
  for (unsigned char c : s) h = (h ^ c) * 1099511628211ull;
  return h;
}

bool ends_with(const std::string& s, const std::string& suffix) {
  return s.size() >= suffix.size() && s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

std::string last_line(const std::string& text) {
  std::istringstream in(text);
  std::string line, last;
  while (std::getline(in, line))
    if (!line.empty() && line.find("Warning") == std::string::npos) last = line;
  return last;
}

}  // namespace

std::vector<std::string> town_names() {
  std::vector<std::string> names;
  for (const auto& [path, text] : embedded_files()) {
    if (path.rfind(kTownPrefix, 0) == 0 && ends_with(path, kTownSuffix))
      names.push_back(path.substr(std::strlen(kTownPrefix),
                                  path.size() - std::strlen(kTownPrefix) - std::strlen(kTownSuffix)));
  }
  return names;
}

TownSpec town_spec(const std::string& name) {
  const auto& files = embedded_files();
  auto it = files.find(kTownPrefix + name + kTownSuffix);
  if (it == files.end()) {
    std::string known;
    for (const auto& n : town_names()) known += (known.empty() ? "" : ", ") + n;
    throw ConfigError("unknown town '" + name + "' (known towns: " + known +
                      "; or give a path to a .net.xml file)");
  }
  Section s = ConfigFile::parse(it->second, it->first);
  TownSpec spec;
  spec.name = s.string("name", name);
  spec.description = s.string("description", "");
  spec.netgenerate_args = s.strings("netgenerate", {});
  s.finish();
  if (spec.netgenerate_args.empty())
    throw ConfigError(it->first + ": netgenerate: must list the generator's options");
  return spec;
}

std::string cache_dir() {
  if (const char* c = std::getenv("CAUSALDRIVE_CACHE"); c && *c) return c;
  if (const char* x = std::getenv("XDG_CACHE_HOME"); x && *x) return std::string(x) + "/causaldrive";
  if (const char* h = std::getenv("HOME"); h && *h) return std::string(h) + "/.cache/causaldrive";
  return "/tmp/causaldrive-cache";
}

std::string ensure_town_net(const std::string& name) {
  TownSpec spec = town_spec(name);
  std::vector<std::string> argv = {"netgenerate"};
  argv.insert(argv.end(), spec.netgenerate_args.begin(), spec.netgenerate_args.end());
  bool has_seed = false;
  for (const auto& a : spec.netgenerate_args) has_seed = has_seed || a == "--seed";
  if (!has_seed) argv.insert(argv.end(), {"--seed", kNetSeed});
  // U-turns inside junctions make standstills that say nothing about a policy (SPEC 1).
  argv.insert(argv.end(), {"--no-turnarounds", "true", "--no-turnarounds.tls", "true"});

  std::string key;
  for (const auto& a : argv) key += a + '\x1f';
  char hash[17];
  std::snprintf(hash, sizeof hash, "%016llx", static_cast<unsigned long long>(fnv1a(key)));
  fs::path dir = fs::path(cache_dir()) / "towns";
  fs::path net = dir / (name + "-" + std::string(hash).substr(0, 12) + ".net.xml");
  if (fs::exists(net)) return net.string();

  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) throw IoError("cannot create cache folder " + dir.string() + ": " + ec.message());
  std::string tmp = temp_path_for(net.string());
  argv.insert(argv.end(), {"--output-file", tmp});
  ProcessResult r = run_process(argv, {"SUMO_HOME=/usr/share/sumo"});
  if (r.exit_code != 0) {
    std::remove(tmp.c_str());
    std::string why = r.exit_code < 0 ? r.output : last_line(r.output);
    throw SimError("netgenerate failed for town '" + name + "': " + why +
                   (r.exit_code < 0 ? " (is the sumo package installed? run 'make setup')" : ""));
  }
  commit_temp_file(tmp, net.string());
  return net.string();
}

std::string resolve_network(const std::string& town_or_path) {
  if (ends_with(town_or_path, ".xml") || town_or_path.find('/') != std::string::npos) {
    std::error_code ec;
    if (!fs::is_regular_file(town_or_path, ec))
      throw IoError("network file not found: " + town_or_path);
    if (access(town_or_path.c_str(), R_OK) != 0)
      throw IoError("network file not readable: " + town_or_path);
    return town_or_path;
  }
  return ensure_town_net(town_or_path);
}

std::string network_label(const std::string& town_or_path) {
  if (ends_with(town_or_path, ".xml") || town_or_path.find('/') != std::string::npos) {
    std::string stem = fs::path(town_or_path).filename().string();
    for (const char* ext : {".net.xml", ".xml"})
      if (ends_with(stem, ext)) return stem.substr(0, stem.size() - std::strlen(ext));
    return stem;
  }
  return town_or_path;
}

}  // namespace cd
