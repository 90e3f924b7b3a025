#pragma once
// What every run record (checkpoint.json, dim.json, run.json) shares: typed JSON access with
// one-line errors, the refusal of a folder that holds another run, and path and number forms.
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace cd {

// Typed access to a JSON object read from `where`: nlohmann's exceptions become one DataError
// naming the file and the key. Shared by every run record (checkpoint.json, dim.json, ...).
struct JsonFields {
  const nlohmann::json& j;
  const std::string& where;

  const nlohmann::json& at(const char* key) const;
  template <class T>
  T get(const char* key) const {
    try {
      return at(key).get<T>();
    } catch (const nlohmann::json::exception&) {
      throw_wrong_type(key);
    }
  }

 private:
  [[noreturn]] void throw_wrong_type(const char* key) const;
};

// "table.key old -> new, ..." for every key of now[table], for each table, whose value differs
// from stored[table] (a missing one counts as null), unless ignore(table, key). Empty when the
// settings agree: how every trainer refuses to resume a folder trained with other settings.
std::string settings_diff(const nlohmann::json& stored, const nlohmann::json& now,
                          const std::vector<std::string>& tables,
                          const std::function<bool(const std::string&, const std::string&)>& ignore);

// The absolute, normalised form of a folder path (as given when it cannot be resolved; "" stays
// ""): how run records name their data and init folders.
std::string canonical_dir(const std::string& dir);

// One finished epoch of a trainer (train/loop.hpp), as run records keep it.
struct EpochMetrics {
  int epoch = 0;  // 1-based
  double train_loss = 0;
  std::optional<double> val_loss;  // none without validation episodes
  double lr = 0;                   // the learning rate the epoch trained with
  double seconds = 0;
  double samples_per_s = 0;        // training samples per second of the training pass
};

// Its JSON form, the loss named `loss` ("train_<loss>", "val_<loss>": null without
// validation), and back (DataError naming `where`).
nlohmann::json epoch_metrics_json(const EpochMetrics& m, const std::string& loss);
EpochMetrics epoch_metrics_from_json(const nlohmann::json& j, const std::string& loss,
                                     const std::string& where);

// Who trained a run folder, as far as a resume must agree with it.
struct RunIdentity {
  std::string method;
  nlohmann::json settings;  // settings_to_json of the effective settings
  std::string inputs;       // the data folder (and reused runs), canonical
};

// Throws ConfigError (one line naming `dir`) when `now` may not continue `stored`: another
// method, a setting of `tables` that differs (unless may_differ(table, key)), other inputs.
void refuse_other_run(const RunIdentity& stored, const RunIdentity& now, const std::string& dir,
                      const std::vector<std::string>& tables,
                      const std::function<bool(const std::string&, const std::string&)>& may_differ);

// Throws ConfigError when `dir` holds the run of another method (a run record naming one):
// used by trainers and agents so a wrong folder is one clear line.
void refuse_other_method_folder(const std::string& dir, const std::string& method);

// JSON number, or null for NaN / infinity.
nlohmann::json json_number(double v);

}  // namespace cd
