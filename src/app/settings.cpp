#include "app/settings.hpp"
#include "app/settings_reference.hpp"

#include <algorithm>
#include <limits>
#include <map>

#include <nlohmann/json.hpp>

#include "core/config.hpp"
#include "core/embedded.hpp"
#include "core/text.hpp"
#include "core/error.hpp"

namespace cd {

namespace {

// Every setting once: its table, key, place in Settings and allowed values. Reading a config
// and writing settings to JSON both walk this list, so they cannot disagree.
template <class S, class V>
void visit_settings(S& st, V&& v) {
  constexpr int64_t kMaxI64 = std::numeric_limits<int64_t>::max();
  v.text("world", "town", st.world.town, {});
  v.text("world", "traffic", st.world.traffic, {"empty", "regular", "dense"});
  v.number("world", "dt", st.world.dt, 0.01, 1.0);
  v.number("world", "warmup_s", st.world.warmup_s, 0, 3600);
  v.number("world", "view_radius", st.world.view_radius, 10, 500);
  v.number("world", "command_horizon", st.world.command_horizon, 0, 500);
  v.number("world", "path_free_margin", st.world.path_free_margin, 0, 100);
  v.number("world", "path_free_decel", st.world.path_free_decel, 0.5, 10);
  v.number("world", "vehicle_margin", st.world.vehicle_margin, 0, 5);
  v.number("world", "ped_margin", st.world.ped_margin, 0, 5);
  v.number("world", "ped_lookahead_s", st.world.ped_lookahead_s, 0, 10);
  v.number("world", "ped_ahead_m", st.world.ped_ahead_m, 0, 100);
  v.number("world", "ped_standing_margin", st.world.ped_standing_margin, 0, 5);
  v.number("world", "yield_time", st.world.yield_time, 0, 30);
  auto density = [&](const char* table, auto& d) {
    v.number(table, "cars_per_km", d.cars_per_km, 0, 200);
    v.number(table, "peds_per_km", d.peds_per_km, 0, 200);
  };
  density("world.density.regular", st.world.regular);
  density("world.density.dense", st.world.dense);

  v.number("ego", "length", st.ego.length, 1, 20);
  v.number("ego", "width", st.ego.width, 0.5, 5);
  v.number("ego", "max_accel", st.ego.max_accel, 0.1, 20);
  v.number("ego", "max_decel", st.ego.max_decel, 0.1, 20);
  v.number("ego", "max_speed", st.ego.max_speed, 1, 80);
  v.number("ego", "rolling", st.ego.rolling, 0, 2);
  v.number("ego", "drag", st.ego.drag, 0, 0.1);
  v.text("ego", "lateral", st.ego.lateral, {"route", "free"});
  v.number("ego", "wheelbase", st.ego.wheelbase, 0.5, 10);
  v.number("ego", "max_steer", st.ego.max_steer, 0.05, 1.2);
  v.number("ego", "steer_rate", st.ego.steer_rate, 0.05, 20);

  v.integer("bev", "height", st.bev.height, 8, 1024);
  v.integer("bev", "width", st.bev.width, 8, 1024);
  v.number("bev", "metres_per_pixel", st.bev.metres_per_pixel, 0.05, 5);
  v.number("bev", "ego_row_fraction", st.bev.ego_row_fraction, 0.0, 1.0);
  v.number("bev", "dash_length", st.bev.dash_length, 0.1, 50);
  v.number("bev", "dash_gap", st.bev.dash_gap, 0.1, 50);
  v.number("bev", "marking_width", st.bev.marking_width, 0.01, 2);
  v.integer("bev", "static_supersample", st.bev.static_supersample, 1, 8);

  v.text("sense", "view", st.view, {"bev", "camera"});
  v.integer("sense.camera", "width", st.camera.width, 8, 4096);
  v.integer("sense.camera", "height", st.camera.height, 8, 4096);
  v.number("sense.camera", "mount_height", st.camera.mount_height, 0.1, 10);
  v.number("sense.camera", "mount_forward", st.camera.mount_forward, -10, 10);
  v.number("sense.camera", "pitch_deg", st.camera.pitch_deg, -45, 60);
  v.number("sense.camera", "hfov_deg", st.camera.hfov_deg, 10, 170);
  v.text("sense.camera", "weather", st.camera.weather, camera_weather_settings());

  v.number("expert", "cruise_speed", st.expert.cruise_speed, 0.5, 40);
  v.number("expert", "turn_speed", st.expert.turn_speed, 0.5, 40);
  v.number("expert", "comfort_decel", st.expert.comfort_decel, 0.5, 10);
  v.number("expert", "min_gap", st.expert.min_gap, 0.5, 20);
  v.number("expert", "headway", st.expert.headway, 0.1, 5);
  v.number("expert", "stop_margin", st.expert.stop_margin, 0, 10);
  v.number("expert", "gain", st.expert.gain, 0.1, 20);

  v.integer("collect", "episodes", st.collect.episodes, 1, 1000000);
  v.integer("collect", "seed", st.collect.seed, 0, kMaxI64);
  v.integer("collect", "workers", st.collect.workers, 1, 256);
  v.text("collect", "out", st.collect.out, {});
  v.number("collect", "min_route_m", st.collect.min_route_m, 0, 1e5);
  v.number("collect", "max_route_m", st.collect.max_route_m, 1, 1e5);
  v.number("collect", "max_episode_s", st.collect.max_episode_s, 0, 1e5);
  v.number("collect", "hold_s", st.collect.hold_s, 0, 60);
  v.flag("collect.noise", "enabled", st.collect.noise.enabled);
  v.number("collect.noise", "rate_per_s", st.collect.noise.rate_per_s, 0, 10);
  v.number("collect.noise", "min_s", st.collect.noise.min_s, 0.1, 60);
  v.number("collect.noise", "max_s", st.collect.noise.max_s, 0.1, 60);
  v.number("collect.noise", "steer", st.collect.noise.steer, 0, 1);
  v.number("collect.augment", "fraction", st.collect.augment.fraction, 0, 1);
  v.number("collect.augment", "shift_m", st.collect.augment.shift_m, 0, 5);
  v.number("collect.augment", "rotate_rad", st.collect.augment.rotate_rad, 0, 1);
  v.text("collect.augment", "cameras", st.collect.augment.cameras, {"random", "sides"});

  v.number("control", "kp", st.control.kp, 0, 100);
  v.number("control", "ki", st.control.ki, 0, 100);
  v.number("control", "kd", st.control.kd, 0, 100);
  v.number("control", "integral_limit", st.control.integral_limit, 0, 100);
  v.number("control", "stop_speed", st.control.stop_speed, 0, 5);
  v.number("control", "hold_brake", st.control.hold_brake, 0, 1);

  v.text("model", "backbone", st.model.backbone, {"small", "resnet34"});
  v.text("model", "head", st.model.head, {"cilrs", "linear"});
  v.integer("model", "history", st.model.history, 1, 64);
  v.integer("model", "history_stride", st.model.history_stride, 1, 100);
  v.text("model", "action_head", st.model.action_head, {"throttle_brake", "target_speed"});
  v.text("model", "pedals", st.model.pedals, {"auto", "two", "signed"});
  v.flag("model", "speed_input", st.model.speed_input);
  v.integer("model", "features", st.model.features, 8, 4096);
  v.number("model", "speed_loss_weight", st.model.speed_loss_weight, 0, 100);
  v.number("model", "dropout", st.model.dropout, 0, 0.95);

  v.integer("train", "epochs", st.train.epochs, 1, 100000);
  v.integer("train", "batch_size", st.train.batch_size, 1, 65536);
  v.number("train", "lr", st.train.lr, 1e-9, 1);
  v.number("train", "weight_decay", st.train.weight_decay, 0, 1);
  v.text("train", "loss", st.train.loss, {"l1", "l2"});
  v.number("train", "val_fraction", st.train.val_fraction, 0, 0.9);
  v.integer("train", "lr_patience", st.train.lr_patience, 0, 1000);
  v.number("train", "lr_decay", st.train.lr_decay, 0.01, 1);
  v.number("train", "lr_min", st.train.lr_min, 0, 1);
  v.integer("train", "seed", st.train.seed, 0, kMaxI64);
  v.integer("train", "threads", st.train.threads, 1, 256);
  v.flag("train", "flush_denormals", st.train.flush_denormals);
  v.text("train", "device", st.train.device, {"auto", "cpu", "cuda"});
  v.text("train", "precision", st.train.precision, {"fp32", "bf16"});
  v.flag("train", "cuda_deterministic", st.train.cuda_deterministic);
  v.integer("train", "max_samples", st.train.max_samples, 0, kMaxI64);
  v.integer("train", "epoch_samples", st.train.epoch_samples, 0, kMaxI64);
  v.text("train", "situation_weights", st.train.situation_weights, {"auto", "none", "balanced"});
  v.number("train", "situation_weight_max", st.train.situation_weight_max, 1, 1000);
  v.text("train", "out", st.train.out, {});

  v.text("eval", "suite", st.eval.suite, {});
  v.integer("eval", "trials", st.eval.trials, 0, 1000);
  v.integer("eval", "workers", st.eval.workers, 1, 256);
  v.text("eval", "out", st.eval.out, {});
  v.text("eval", "device", st.eval.device, {"auto", "cpu", "cuda"});
  v.number("eval", "prefill_s", st.eval.prefill_s, 0, 60);
  v.number("eval", "cs_speed", st.eval.cs_speed, 0.5, 40);
  v.integer("eval", "max_attempts", st.eval.max_attempts, 1, 100);
  v.text("eval", "batch", st.eval.batch, {"auto", "on", "off"});
  v.text("eval", "sensor", st.eval.sensor, {"clean", "shifted"});
  v.integer("eval", "sensor_seed", st.eval.sensor_shift.seed, 0, kMaxI64);
  v.number("eval", "sensor_miss", st.eval.sensor_shift.miss, 0, 1);
  v.number("eval", "sensor_jitter_m", st.eval.sensor_shift.jitter_m, 0, 10);
  v.number("eval", "sensor_ghosts", st.eval.sensor_shift.ghosts, 0, 20);
  v.number("eval", "sensor_fade", st.eval.sensor_shift.fade, 0, 1);
  v.text("eval", "cim_path", st.eval.cim_path, {});

  v.text("vae", "view", st.vae.view, {});
  v.integer("vae", "latents", st.vae.latents, 1, 4096);
  v.number("vae", "beta", st.vae.beta, 0, 1000);
  v.integer("vae", "epochs", st.vae.epochs, 1, 100000);
  v.integer("vae", "patience", st.vae.patience, 0, 100000);
  v.number("vae", "min_improvement", st.vae.min_improvement, 0, 1);
  v.integer("vae", "batch_size", st.vae.batch_size, 1, 65536);
  v.number("vae", "lr", st.vae.lr, 1e-9, 1);
  v.integer("vae", "max_frames", st.vae.max_frames, 0, kMaxI64);

  v.integer("cim", "lags", st.cim.lags, 1, 100);
  v.number("cim", "alpha", st.cim.alpha, 1e-300, 1);
  v.text("cim", "correction", st.cim.correction, {"none", "bonferroni", "bh"});
  v.integer("cim", "max_causes", st.cim.max_causes, 0, 4096);
  v.text("cim", "selection", st.cim.selection, {"bivariate", "conditional", "partial_r2"});
  v.text("cim", "candidates", st.cim.candidates, {"all", "active"});
  v.number("cim", "min_partial_r2", st.cim.min_partial_r2, 0, 1);
  v.integer("cim", "series_stride", st.cim.series_stride, 1, 1000);
  v.integer("cim", "history", st.cim.history, 1, 64);
  v.integer("cim", "history_stride", st.cim.history_stride, 1, 100);
  v.integer("cim", "fewshot_steps", st.cim.fewshot_steps, 1, 10000000);
  v.integer("cim", "encoder_units", st.cim.encoder_units, 1, 4096);
  v.integer("cim", "mlp_encoder_units", st.cim.mlp_encoder_units, 1, 4096);
  v.integer("cim", "hidden", st.cim.hidden, 1, 4096);
  v.integer("cim", "epochs", st.cim.epochs, 1, 100000);
  v.integer("cim", "batch_size", st.cim.batch_size, 1, 65536);
  v.number("cim", "lr", st.cim.lr, 1e-9, 1);

  v.integer("dim", "horizon", st.dim.horizon, 1, 100);
  v.integer("dim", "waypoint_step", st.dim.waypoint_step, 1, 100);
  v.integer("dim", "past", st.dim.past, 1, 100);
  v.integer("dim", "features", st.dim.features, 8, 4096);
  v.integer("dim", "hidden", st.dim.hidden, 8, 4096);
  v.number("dim", "min_std", st.dim.min_std, 1e-4, 10);
  v.integer("dim", "plan_iterations", st.dim.plan_iterations, 0, 10000);
  v.integer("dim", "replan_steps", st.dim.replan_steps, 1, 100);
  v.number("dim", "plan_lr", st.dim.plan_lr, 0, 100);
  v.number("dim", "goal_distance", st.dim.goal_distance, 0, 1000);
  v.number("dim", "goal_weight", st.dim.goal_weight, 0, 1000);
  v.text("dim", "goal", st.dim.goal, {"point", "segment"});
  v.text("dim", "plan_speed", st.dim.plan_speed, {"first", "horizon"});
  v.integer("dim", "ensemble", st.dim.ensemble, 1, 64);
  v.integer("dim", "patience", st.dim.patience, 0, 100000);
  v.text("dim", "aggregation", st.dim.aggregation, {"worst", "mean"});
  v.text("dim", "view", st.dim.view, {});

  v.integer("residual", "branches", st.residual.branches, 1, 16);
  v.text("residual", "memory_target", st.residual.memory_target, {"residual", "action", "previous"});
  v.text("residual", "policy", st.residual.policy,
         {"stream", "residual_controller", "learned_controller"});
  v.text("residual", "policy_input", st.residual.policy_input, {"current", "history"});
  v.text("residual", "weights", st.residual.weights, {"none", "keyframe"});

  v.number("fca", "adversary_weight", st.fca.adversary_weight, 0, 1000);
  v.integer("fca", "hidden", st.fca.hidden, 1, 4096);
  v.number("fca", "beta1", st.fca.beta1, 0, 0.999);

  v.text("keyframe", "mode", st.keyframe.mode, {"threshold", "softmax"});
  v.integer("keyframe", "actions", st.keyframe.actions, 1, 64);
  v.integer("keyframe", "hidden", st.keyframe.hidden, 1, 4096);
  v.integer("keyframe", "epochs", st.keyframe.epochs, 1, 100000);
  v.integer("keyframe", "batch_size", st.keyframe.batch_size, 1, 65536);
  v.number("keyframe", "lr", st.keyframe.lr, 1e-9, 1);
  v.number("keyframe", "top_fraction", st.keyframe.top_fraction, 0, 1);
  v.number("keyframe", "top_weight", st.keyframe.top_weight, 0, 1000);
  v.number("keyframe", "temperature", st.keyframe.temperature, 1e-6, 1e6);

  v.number("hd", "p", st.hd.p, 0, 1);

  v.integer("dagger", "iterations", st.dagger.iterations, 1, 100);
  v.integer("dagger", "episodes", st.dagger.episodes, 1, 100000);
  v.number("dagger", "beta", st.dagger.beta, 0, 1);
  v.number("dagger", "beta_decay", st.dagger.beta_decay, 0, 1);
  v.integer("dagger", "epochs", st.dagger.epochs, 1, 100000);
  v.integer("dagger", "seed", st.dagger.seed, 0, kMaxI64);
  v.text("dagger", "town", st.dagger.town, {});
  v.text("dagger", "traffic", st.dagger.traffic, {});

  v.integer("mujoco", "size", st.mujoco.size, 8, 1024);
  v.integer("mujoco", "workers", st.mujoco.workers, 1, 256);
  v.integer("mujoco", "seed", st.mujoco.seed, 0, kMaxI64);
  v.integer("mujoco", "max_steps", st.mujoco.max_steps, 0, 1000000);
  v.integer("mujoco", "eval_episodes", st.mujoco.eval_episodes, 1, 1000000);
  v.integer("mujoco", "planner_samples", st.mujoco.planner_samples, 0, 100000);
  v.integer("mujoco", "planner_horizon", st.mujoco.planner_horizon, 0, 100000);
  v.integer("mujoco", "planner_iterations", st.mujoco.planner_iterations, 0, 1000);
  v.number("mujoco", "planner_sigma", st.mujoco.planner_sigma, 0, 10);
  v.number("mujoco", "planner_temperature", st.mujoco.planner_temperature, 0, 1e6);
  v.number("mujoco", "planner_smoothing", st.mujoco.planner_smoothing, -1, 0.999);
  v.number("mujoco", "planner_terminal_steps", st.mujoco.planner_terminal_steps, -1, 1e6);
  v.text("mujoco", "expert_policies", st.mujoco.expert_policies, {});
  v.integer("mujoco.episodes", "halfcheetah", st.mujoco.episodes.halfcheetah, 1, 1000000);
  v.integer("mujoco.episodes", "hopper", st.mujoco.episodes.hopper, 1, 1000000);
  v.integer("mujoco.episodes", "ant", st.mujoco.episodes.ant, 1, 1000000);
  v.integer("mujoco.episodes", "reacher", st.mujoco.episodes.reacher, 1, 1000000);
  v.integer("mujoco.episodes", "humanoid", st.mujoco.episodes.humanoid, 1, 1000000);
  v.flag("mujoco.noise", "enabled", st.mujoco.noise.enabled);
  v.number("mujoco.noise", "rate", st.mujoco.noise.rate, 0, 1);
  v.integer("mujoco.noise", "min_steps", st.mujoco.noise.min_steps, 1, 100000);
  v.integer("mujoco.noise", "max_steps", st.mujoco.noise.max_steps, 1, 100000);
  v.number("mujoco.noise", "sigma", st.mujoco.noise.sigma, 0, 10);
}

// "world.density.regular" -> {"world", "density", "regular"}: a table's place in nested JSON.
std::vector<std::string> table_path(const std::string& table) {
  std::vector<std::string> parts;
  size_t start = 0;
  while (start <= table.size()) {
    size_t dot = table.find('.', start);
    if (dot == std::string::npos) dot = table.size();
    parts.push_back(table.substr(start, dot - start));
    start = dot + 1;
  }
  return parts;
}

// Reads each field from its table; tables are opened once, and checked for unknown keys
// after every field was read.
class Reader {
 public:
  explicit Reader(Section root) : root_(std::move(root)) {}

  void number(const std::string& table, const char* key, double& x, double lo, double hi) {
    x = at(table).number(key, x, lo, hi);
  }
  template <class I>
  void integer(const std::string& table, const char* key, I& x, int64_t lo, int64_t hi) {
    x = static_cast<I>(at(table).integer(key, static_cast<int64_t>(x), lo, hi));
  }
  void text(const std::string& table, const char* key, std::string& x,
            const std::vector<std::string>& allowed) {
    x = at(table).string(key, x, allowed);
  }
  void flag(const std::string& table, const char* key, bool& x) {
    x = at(table).boolean(key, x);
  }
  void finish() {
    for (const auto& [name, section] : tables_) section.finish();
    root_.finish();
  }

 private:
  // "world.density.regular" -> root.section("world").section("density").section("regular")
  const Section& at(const std::string& path) {
    auto it = tables_.find(path);
    if (it != tables_.end()) return it->second;
    auto dot = path.rfind('.');
    const Section& parent = dot == std::string::npos ? root_ : at(path.substr(0, dot));
    Section s = parent.section(dot == std::string::npos ? path : path.substr(dot + 1));
    return tables_.emplace(path, std::move(s)).first->second;
  }
  Section root_;
  std::map<std::string, Section> tables_;
};

// Writes each field into a nested JSON object.
struct Writer {
  nlohmann::json out = nlohmann::json::object();

  template <class T>
  void put(const std::string& table, const char* key, const T& x) {
    nlohmann::json* node = &out;
    for (const std::string& part : table_path(table)) node = &(*node)[part];
    (*node)[key] = x;
  }
  void number(const std::string& t, const char* k, const double& x, double, double) { put(t, k, x); }
  template <class I>
  void integer(const std::string& t, const char* k, const I& x, int64_t, int64_t) { put(t, k, x); }
  void text(const std::string& t, const char* k, const std::string& x,
            const std::vector<std::string>&) {
    put(t, k, x);
  }
  void flag(const std::string& t, const char* k, const bool& x) { put(t, k, x); }
};

// Reads each field back from the nested JSON object settings_to_json wrote (a run record's
// "settings"), with the ranges of a config file. A missing table or key keeps its default
// (records written before a key existed); a wrong type or an out-of-range value is a DataError
// naming the record and the key.
class JsonReader {
 public:
  JsonReader(const nlohmann::json& root, const std::string& where) : root_(root), where_(where) {}

  void number(const std::string& table, const char* key, double& x, double lo, double hi) {
    if (const nlohmann::json* v = find(table, key)) {
      if (!v->is_number()) bad(table, key, "is not a number");
      x = v->get<double>();
      if (!(x >= lo && x <= hi)) bad(table, key, "is out of range");
    }
  }
  template <class I>
  void integer(const std::string& table, const char* key, I& x, int64_t lo, int64_t hi) {
    if (const nlohmann::json* v = find(table, key)) {
      if (!v->is_number_integer()) bad(table, key, "is not an integer");
      const int64_t i = v->get<int64_t>();
      if (i < lo || i > hi) bad(table, key, "is out of range");
      x = static_cast<I>(i);
    }
  }
  void text(const std::string& table, const char* key, std::string& x,
            const std::vector<std::string>& allowed) {
    if (const nlohmann::json* v = find(table, key)) {
      if (!v->is_string()) bad(table, key, "is not a string");
      x = v->get<std::string>();
      if (!allowed.empty() && std::find(allowed.begin(), allowed.end(), x) == allowed.end())
        bad(table, key, "has an unknown value '" + x + "'");
    }
  }
  void flag(const std::string& table, const char* key, bool& x) {
    if (const nlohmann::json* v = find(table, key)) {
      if (!v->is_boolean()) bad(table, key, "is not a boolean");
      x = v->get<bool>();
    }
  }

 private:
  const nlohmann::json* find(const std::string& table, const char* key) const {
    const nlohmann::json* node = &root_;
    for (const std::string& part : table_path(table)) {
      if (!node->is_object() || !node->contains(part)) return nullptr;
      node = &(*node)[part];
    }
    if (!node->is_object() || !node->contains(key)) return nullptr;
    return &(*node)[key];
  }
  [[noreturn]] void bad(const std::string& table, const char* key, const std::string& why) const {
    throw DataError(where_ + ": setting " + table + "." + key + " " + why);
  }
  const nlohmann::json& root_;
  const std::string& where_;
};

}  // namespace

Settings settings_from_json(const nlohmann::json& j, const std::string& where) {
  if (!j.is_object()) throw DataError(where + ": the settings are not a JSON object");
  Settings st;
  // Keys whose default changed after records were written without them (the validated recipe
  // became the default on 2026-11-27): such a record was made with the value of its time.
  st.collect.hold_s = 0;
  st.model.pedals = "two";
  st.train.situation_weights = "none";
  st.source = where;
  JsonReader reader(j, where);
  visit_settings(st, reader);
  return st;
}

namespace {

// Reads `root` over `st` (absent keys keep st's values) and checks what spans several keys.
Settings read_settings(Settings st, Section root, const std::string& where) {
  Reader reader(std::move(root));
  visit_settings(st, reader);
  reader.finish();
  if (st.collect.max_route_m < st.collect.min_route_m)
    throw ConfigError(where + ": collect.max_route_m must be >= collect.min_route_m");
  if (st.collect.noise.max_s < st.collect.noise.min_s)
    throw ConfigError(where + ": collect.noise.max_s must be >= collect.noise.min_s");
  if (st.mujoco.noise.max_steps < st.mujoco.noise.min_steps)
    throw ConfigError(where + ": mujoco.noise.max_steps must be >= mujoco.noise.min_steps");
  return st;
}

}  // namespace

Settings load_settings(const std::string& path) {
  Settings st;
  st.source = path;
  return read_settings(st, ConfigFile::load(path), path);
}

Settings override_settings(const Settings& base, const std::string& toml,
                           const std::string& where) {
  return read_settings(base, ConfigFile::parse(toml, where), where);
}

nlohmann::json settings_to_json(const Settings& s) {
  Writer writer;
  visit_settings(s, writer);
  return writer.out;
}

namespace {

// One row of the reference per setting.
struct Referencer {
  struct Row {
    std::string table, key, type, value, allowed;
  };
  std::vector<Row> rows;

  static std::string num(double x) {
    char buf[40];
    std::snprintf(buf, sizeof buf, "%g", x);
    return buf;
  }
  static std::string range(const std::string& lo, const std::string& hi, bool unbounded) {
    return unbounded ? ">= " + lo : lo + " to " + hi;
  }
  void number(const std::string& t, const char* k, const double& x, double lo, double hi) {
    rows.push_back({t, k, "number", num(x), range(num(lo), num(hi), hi >= 1e12)});
  }
  template <class I>
  void integer(const std::string& t, const char* k, const I& x, int64_t lo, int64_t hi) {
    rows.push_back({t, k, "integer", std::to_string(x),
                    range(std::to_string(lo), std::to_string(hi),
                          hi == std::numeric_limits<int64_t>::max())});
  }
  void text(const std::string& t, const char* k, const std::string& x,
            const std::vector<std::string>& allowed) {
    std::string a;
    for (const std::string& v : allowed) a += (a.empty() ? "" : ", ") + ("`\"" + v + "\"`");
    rows.push_back({t, k, "text", "\"" + x + "\"", a});
  }
  void flag(const std::string& t, const char* k, const bool& x) {
    rows.push_back({t, k, "true/false", x ? "true" : "false", ""});
  }
};

// table.key -> the comment after its line in the built-in config ("table." -> the table's).
std::map<std::string, std::string> default_config_comments() {
  std::map<std::string, std::string> out;
  const std::string& text = embedded_files().at("configs/quickstart.toml");
  std::string table;
  size_t start = 0;
  while (start < text.size()) {
    size_t end = text.find('\n', start);
    if (end == std::string::npos) end = text.size();
    std::string line = text.substr(start, end - start);
    start = end + 1;
    const size_t hash = line.find('#');
    std::string code = line.substr(0, hash), comment;
    if (hash != std::string::npos) comment = line.substr(hash + 1);
    code = std::string(trim(code));
    if (code.size() > 2 && code.front() == '[' && code.back() == ']') {
      table = code.substr(1, code.size() - 2);
      if (!trim(comment).empty()) out[table + "."] = std::string(trim(comment));  // the table's own
      continue;
    }
    const size_t eq = code.find('=');
    if (eq == std::string::npos || trim(comment).empty()) continue;
    out[table + "." + std::string(trim(code.substr(0, eq)))] = std::string(trim(comment));
  }
  return out;
}

}  // namespace

std::string settings_reference_markdown() {
  Settings st;
  Referencer r;
  visit_settings(st, r);
  const std::map<std::string, std::string> comments = default_config_comments();
  std::string md =
      "# Configuration reference\n\n"
      "[Back to the README](../README.md) \u00b7 [all pages](README.md)\n\n"
      "Every key of a causaldrive TOML config, table by table, generated by `causaldrive config "
      "--reference` from the one list of settings (`visit_settings` in `src/app/settings.cpp`): "
      "a test fails when this page differs from what the binary prints. The defaults are the "
      "built-in ones, which are `configs/quickstart.toml` (compiled in); the comments are that "
      "file's. A config names only what it changes; an unknown table or key, a value of the "
      "wrong type or out of range is one error line naming the file and the key.\n";
  std::string table;
  auto cell = [](std::string s) {
    for (size_t at = 0; (at = s.find('|', at)) != std::string::npos; at += 2) s.replace(at, 1, "\\|");
    return s;
  };
  for (const Referencer::Row& row : r.rows) {
    if (row.table != table) {
      table = row.table;
      md += "\n## [" + table + "]\n\n";
      auto about = comments.find(table + ".");
      if (about != comments.end()) md += about->second + "\n\n";
      md += "| key | type | default | allowed | what it is |\n|---|---|---|---|---|\n";
    }
    auto it = comments.find(row.table + "." + row.key);
    md += "| `" + row.key + "` | " + row.type + " | `" + cell(row.value) + "` | " +
          cell(row.allowed) + " | " + (it == comments.end() ? "" : cell(it->second)) + " |\n";
  }
  return md;
}

}  // namespace cd
