#include "runs/cim_run.hpp"

#include <algorithm>
#include <filesystem>

#include "core/atomic_file.hpp"
#include "core/error.hpp"

namespace cd {

bool CimRunInfo::has_stage(const std::string& stage) const {
  return std::find(stages.begin(), stages.end(), stage) != stages.end();
}

std::optional<CimRunInfo> read_cim_run(const std::string& dir) {
  const std::string path = dir + "/" + kCimRunJson;
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) return std::nullopt;
  CimRunInfo r;
  r.dir = dir;
  try {
    r.record = nlohmann::json::parse(read_file_bytes(path));
    const auto& j = r.record;
    r.method = j.at("method").get<std::string>();
    r.data_dir = j.at("data_dir").get<std::string>();
    r.init = j.value("init", "");
    r.vae_from = j.value("vae_from", "");
    r.stages = j.at("stages").get<std::vector<std::string>>();
    const auto& in = j.at("input");
    r.channels = in.at("channels").get<int>();
    r.height = in.at("height").get<int>();
    r.width = in.at("width").get<int>();
    r.channel_names = in.at("channel_names").get<std::vector<std::string>>();
    const Settings settings = settings_from_json(j.at("settings"), path);
    r.vae = settings.vae;
    r.cim = settings.cim;
  } catch (const nlohmann::json::exception& e) {
    throw DataError(path + " is damaged (" + e.what() + "): delete the folder to start over");
  }
  return r;
}

CimRunInfo require_cim_run(const std::string& dir, const std::string& method,
                           const std::vector<std::string>& stages, const std::string& role) {
  std::error_code ec;
  if (!std::filesystem::is_directory(dir, ec))
    throw ConfigError(role + " " + dir + ": no such run folder");
  std::optional<CimRunInfo> r = read_cim_run(dir);
  if (!r)
    throw ConfigError(role + " " + dir + " is not a cim run folder (no " + kCimRunJson +
                      "; train it with causaldrive train --method cim ...)");
  if (r->method.rfind("cim", 0) != 0 || (!method.empty() && r->method != method))
    throw ConfigError(role + " " + dir + " holds a run of method '" + r->method + "', not '" +
                      (method.empty() ? std::string("cim*") : method) + "'");
  for (const auto& st : stages)
    if (!r->has_stage(st))
      throw ConfigError(role + " " + dir + " is unfinished (stage '" + st +
                        "' not done): finish it with causaldrive train first");
  return *r;
}

}  // namespace cd
