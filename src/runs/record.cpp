#include "runs/record.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>

#include "app/settings.hpp"
#include "core/atomic_file.hpp"
#include "core/error.hpp"

namespace cd {

namespace fs = std::filesystem;
using nlohmann::json;

const json& JsonFields::at(const char* key) const {
  if (!j.is_object() || !j.contains(key)) throw DataError(where + ": missing key '" + key + "'");
  return j.at(key);
}

void JsonFields::throw_wrong_type(const char* key) const {
  throw DataError(where + ": key '" + key + "' has the wrong type");
}

std::string settings_diff(const json& stored, const json& now,
                          const std::vector<std::string>& tables,
                          const std::function<bool(const std::string&, const std::string&)>& ignore) {
  std::string diff;
  for (const std::string& table : tables) {
    const json& a = stored.contains(table) ? stored.at(table) : json::object();
    const json& b = now.at(table);
    for (auto it = b.begin(); it != b.end(); ++it) {
      if (ignore(table, it.key())) continue;
      const json old = a.contains(it.key()) ? a.at(it.key()) : json();
      if (old == it.value()) continue;
      diff += (diff.empty() ? "" : ", ") + table + "." + it.key() + " " + old.dump() + " -> " +
              it.value().dump();
    }
  }
  return diff;
}

std::string canonical_dir(const std::string& dir) {
  if (dir.empty()) return dir;
  std::error_code ec;
  std::filesystem::path p = std::filesystem::weakly_canonical(std::filesystem::absolute(dir), ec);
  return ec ? dir : p.string();
}

void refuse_other_method_folder(const std::string& dir, const std::string& method) {
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) return;
  std::vector<fs::path> records;
  for (const auto& entry : fs::directory_iterator(dir, ec))
    if (entry.path().extension() == ".json") records.push_back(entry.path());
  std::sort(records.begin(), records.end());
  for (const fs::path& p : records) {
    std::string other;
    try {
      json j = json::parse(read_file_bytes(p.string()));
      if (j.is_object() && j.contains("method") && j["method"].is_string())
        other = j["method"].get<std::string>();
    } catch (const std::exception&) {
      continue;  // not a run record: the caller's own checks decide
    }
    if (!other.empty() && other != method)
      throw ConfigError(dir + " holds a run of method '" + other + "' (" +
                        p.filename().string() + "), not '" + method +
                        "': use another folder");
  }
}

void refuse_other_run(const RunIdentity& stored, const RunIdentity& now, const std::string& dir,
                      const std::vector<std::string>& tables,
                      const std::function<bool(const std::string&, const std::string&)>& may_differ) {
  if (stored.method != now.method)
    throw ConfigError(dir + " holds a run of method '" + stored.method + "', not '" + now.method +
                      "': train into another --out folder");
  // A key the record lacks (written before the key existed) takes its default: the run was
  // trained with the behaviour the default keeps.
  const nlohmann::json stored_settings =
      stored.settings.is_object()
          ? settings_to_json(settings_from_json(stored.settings, dir + " (its run record)"))
          : stored.settings;
  const std::string diff = settings_diff(stored_settings, now.settings, tables, may_differ);
  if (!diff.empty())
    throw ConfigError(dir + " holds a " + now.method + " run trained with other settings (" + diff +
                      "): train into another --out folder, or delete it to start over");
  if (stored.inputs != now.inputs)
    throw ConfigError(dir + " holds a run trained on " + stored.inputs + ", not " + now.inputs +
                      ": train into another --out folder");
}

json epoch_metrics_json(const EpochMetrics& m, const std::string& loss) {
  json j = {{"epoch", m.epoch},
            {"train_" + loss, m.train_loss},
            {"val_" + loss, nullptr},
            {"lr", m.lr},
            {"seconds", m.seconds},
            {"samples_per_s", m.samples_per_s}};
  if (m.val_loss) j["val_" + loss] = *m.val_loss;
  return j;
}

EpochMetrics epoch_metrics_from_json(const json& j, const std::string& loss,
                                     const std::string& where) {
  JsonFields f{j, where};
  const std::string train_key = "train_" + loss, val_key = "val_" + loss;
  EpochMetrics m;
  m.epoch = f.get<int>("epoch");
  m.train_loss = f.get<double>(train_key.c_str());
  if (!f.at(val_key.c_str()).is_null()) m.val_loss = f.get<double>(val_key.c_str());
  m.lr = f.get<double>("lr");
  m.seconds = f.get<double>("seconds");
  m.samples_per_s = f.get<double>("samples_per_s");
  return m;
}

json json_number(double v) { return std::isfinite(v) ? json(v) : json(nullptr); }

}  // namespace cd
