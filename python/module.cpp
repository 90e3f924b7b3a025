// causaldrive._core: the C++ library seen from Python (SPEC section 9). The package around it
// (python/causaldrive/__init__.py) adds the spaces, make() and the Gymnasium registration; this
// file only converts: numpy arrays in and out (frames are rendered straight into the array
// Python receives, episode arrays handed over without a copy), dicts for settings and results,
// and the library's errors as Python exceptions carrying the same one-line messages.
#include <pybind11/functional.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <cmath>
#include <memory>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "agents/agent.hpp"
#include "app/settings.hpp"
#include "bench/runner.hpp"
#include "collect/expert_episode.hpp"
#include "core/error.hpp"
#include "core/rng.hpp"
#include "data/h5_episode.hpp"
#include "data/mujoco_episode.hpp"
#include "gym/driving_env.hpp"
#include "methods/method.hpp"
#include "mujoco/env.hpp"
#include "mujoco/expert.hpp"
#include "sense/bev.hpp"
#include "world/ground_truth.hpp"
#include "world/town.hpp"

namespace py = pybind11;

namespace cd::python {

namespace {

// ---------------------------------------------------------------- errors

PyObject* g_error = nullptr;
PyObject* g_config_error = nullptr;
PyObject* g_data_error = nullptr;
PyObject* g_io_error = nullptr;
PyObject* g_sim_error = nullptr;

PyObject* new_exception(py::module_& m, const char* name, py::tuple bases, const char* doc) {
  const std::string qualified = std::string("causaldrive.") + name;
  PyObject* type = PyErr_NewExceptionWithDoc(qualified.c_str(), doc, bases.ptr(), nullptr);
  if (!type) throw py::error_already_set();
  m.attr(name) = py::handle(type);
  return type;
}

void register_errors(py::module_& m) {
  g_error = new_exception(m, "Error", py::make_tuple(py::handle(PyExc_RuntimeError)),
                          "Any causaldrive error (a RuntimeError).");
  py::handle base(g_error);
  g_config_error = new_exception(m, "ConfigError", py::make_tuple(base, py::handle(PyExc_ValueError)),
                                 "Bad configuration or argument (also a ValueError).");
  g_data_error = new_exception(m, "DataError", py::make_tuple(base, py::handle(PyExc_ValueError)),
                               "A malformed or inconsistent data file (also a ValueError).");
  g_io_error = new_exception(m, "IoError", py::make_tuple(base),
                             "A file that cannot be read or written.");
  g_sim_error = new_exception(m, "SimError", py::make_tuple(base),
                              "The simulator refused something or failed.");
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const ConfigError& e) {
      PyErr_SetString(g_config_error, e.what());
    } catch (const DataError& e) {
      PyErr_SetString(g_data_error, e.what());
    } catch (const IoError& e) {
      PyErr_SetString(g_io_error, e.what());
    } catch (const SimError& e) {
      PyErr_SetString(g_sim_error, e.what());
    } catch (const Error& e) {
      PyErr_SetString(g_error, e.what());
    }
  });
}

// ---------------------------------------------------------------- settings

// A Python value as a TOML value: str, bool, int, float, or a list of those.
std::string toml_value(const py::handle& v, const std::string& key) {
  if (py::isinstance<py::bool_>(v)) return v.cast<bool>() ? "true" : "false";
  if (py::isinstance<py::int_>(v)) return std::to_string(v.cast<long long>());
  if (py::isinstance<py::float_>(v)) {
    const double x = v.cast<double>();
    if (!std::isfinite(x)) throw ConfigError("settings: " + key + " is not a finite number");
    std::ostringstream o;
    o.precision(17);
    o << x;
    std::string s = o.str();
    if (s.find_first_of(".eE") == std::string::npos) s += ".0";
    return s;
  }
  if (py::isinstance<py::str>(v)) {
    std::string s = v.cast<std::string>(), out = "\"";
    for (char c : s) {
      if (c == '"' || c == '\\') out += '\\';
      if (c == '\n') { out += "\\n"; continue; }
      out += c;
    }
    return out + "\"";
  }
  if (py::isinstance<py::list>(v) || py::isinstance<py::tuple>(v)) {
    std::string out = "[";
    for (const py::handle& item : v) out += (out.size() > 1 ? ", " : "") + toml_value(item, key);
    return out + "]";
  }
  throw ConfigError("settings: " + key + " has a value of type " +
                    std::string(py::str(v.get_type().attr("__name__"))) +
                    " (expected str, bool, int, float or a list)");
}

// The settings of `config` (a TOML file; None: the built-in defaults) with the dict's keys
// ("world.traffic": "dense") set over them.
Settings settings_of(const std::optional<std::string>& config, const std::optional<py::dict>& over) {
  Settings s = config && !config->empty() ? load_settings(*config) : Settings{};
  if (!over || over->empty()) return s;
  std::string toml;
  for (const auto& [k, v] : *over) {
    if (!py::isinstance<py::str>(k)) throw ConfigError("settings: keys must be strings like \"world.traffic\"");
    const std::string key = k.cast<std::string>();
    for (char c : key)
      if (!(std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '.'))
        throw ConfigError("settings: '" + key + "' is not a key (table.key, e.g. world.traffic)");
    toml += key + " = " + toml_value(v, key) + "\n";
  }
  return override_settings(s, toml, "settings");
}

// ---------------------------------------------------------------- arrays

// A numpy array that owns `values` (moved, not copied).
template <class T, class V>
py::array owning_array(V&& values, std::vector<py::ssize_t> shape) {
  auto* holder = new std::decay_t<V>(std::forward<V>(values));
  py::capsule owner(holder, [](void* p) { delete static_cast<std::decay_t<V>*>(p); });
  return py::array_t<T>(shape, holder->data(), owner);
}

// An action as doubles: a 1-d array-like of exactly `dim` (or, with dim_max, dim to dim_max)
// finite numbers, else ConfigError.
std::vector<double> action_values(const py::handle& action, int dim, const char* names,
                                  int dim_max = 0) {
  py::array_t<double, py::array::c_style | py::array::forcecast> a;
  try {
    a = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(action);
  } catch (const py::error_already_set&) {
    a = {};
  }
  if (!a) throw ConfigError(std::string("the action is not an array of numbers (expected ") +
                            std::to_string(dim) + " values: " + names + ")");
  std::ostringstream shape;
  shape << "(";
  for (py::ssize_t i = 0; i < a.ndim(); ++i) shape << (i ? ", " : "") << a.shape(i);
  shape << (a.ndim() == 1 ? ",)" : ")");
  const py::ssize_t hi = std::max(dim, dim_max);
  if (a.ndim() != 1 || a.shape(0) < dim || a.shape(0) > hi)
    throw ConfigError("the action has shape " + shape.str() + ", expected (" + std::to_string(dim) +
                      (hi > dim ? ",) or (" + std::to_string(hi) : std::string()) + ",): " + names);
  std::vector<double> v(a.data(), a.data() + a.shape(0));
  for (double x : v)
    if (!std::isfinite(x)) throw ConfigError("the action holds a value that is not finite");
  return v;
}

py::array_t<float> float_array(std::initializer_list<double> values) {
  py::array_t<float> a(static_cast<py::ssize_t>(values.size()));
  float* p = a.mutable_data();
  for (double v : values) *p++ = static_cast<float>(v);
  return a;
}

// The expert's action in full precision: stepping with it executes exactly what `collect`
// executes (the file keeps it as float32).
py::array_t<double> double_array(std::initializer_list<double> values) {
  py::array_t<double> a(static_cast<py::ssize_t>(values.size()));
  std::copy(values.begin(), values.end(), a.mutable_data());
  return a;
}

py::object json_to_python(const nlohmann::json& j) {
  return py::module_::import("json").attr("loads")(j.dump());
}

// ---------------------------------------------------------------- driving

// One libsumo simulation per process (World refuses a second one): the driving environment and
// evaluate() take turns, and the refusal names the way out.
void claim_world(const char* what) {
  if (World::alive())
    throw Error(std::string(what) +
                ": a driving environment is open in this process (libsumo runs one simulation "
                "per process); close() it first");
}

class PyDrivingEnv {
 public:
  PyDrivingEnv(const std::string& name, const std::optional<std::string>& config,
               const std::optional<py::dict>& settings) {
    claim_world("make");
    env_ = std::make_unique<DrivingEnv>(name, settings_of(config, settings));
  }
  ~PyDrivingEnv() { close(); }

  void close() { env_.reset(); }

  DrivingEnv& env() {
    if (!env_) throw Error("the environment is closed");
    return *env_;
  }

  py::tuple reset(std::optional<uint64_t> seed, std::optional<int> episode) {
    env().reset(seed, episode.value_or(-1));
    return py::make_tuple(observation(), info(nullptr));
  }

  bool steers() { return env().world().free_lateral(); }

  py::tuple step(const py::handle& action) {
    const bool free = steers();
    const std::vector<double> a =
        action_values(action, free ? 3 : 2, free ? "throttle, brake, steer" : "throttle, brake");
    EnvStep s = env().step(Control{a[0], a[1], free ? a[2] : 0.0});
    return py::make_tuple(observation(), s.reward, s.terminated, s.truncated, info(&s));
  }

  py::dict observation() {
    const World& w = env().world();
    const FrameFormat& f = w.frame_format();
    py::array_t<uint8_t> frame({static_cast<py::ssize_t>(f.channels),
                                static_cast<py::ssize_t>(f.height),
                                static_cast<py::ssize_t>(f.width)});
    w.render(frame.mutable_data());
    py::dict obs;
    obs[f.view.c_str()] = frame;  // "bev" or "camera" (sense.view)
    obs["speed"] = float_array({w.ego().speed});
    obs["command"] = w.command();
    return obs;
  }

  py::dict info(const EnvStep* s) {
    DrivingEnv& e = env();
    const World& w = e.world();
    py::dict causes;
    for (const CauseSeries& c : cause_schema()) causes[c.name] = c.value(w.truth());
    py::dict info;
    info["causes"] = causes;
    info["time_s"] = w.time();
    info["progress_m"] = e.progress();
    info["route_length_m"] = e.task().route_length;
    if (e.has_suite()) info["episode"] = e.episode();
    info["seed"] = e.episode_seed();
    if (e.running()) info["expert_action"] = expert_action();
    if (w.free_lateral()) {
      const RoadContact& rc = w.road_contact();
      info["lateral_error_m"] = rc.lateral_error;
      info["heading_error"] = rc.heading_error;
      info["steer_angle"] = w.steer_angle();
    }
    if (s && s->result.outcome == Outcome::Collision) info["collided_with"] = s->result.collided_with;
    if (!e.running()) {
      info["outcome"] = e.result().outcome;
      info["episode_record"] = json_to_python(episode_to_json(e.result()));
    }
    return info;
  }

  // Episode `episode` of the suite driven by a C++ agent through the benchmark runner's loop
  // (run_episode, as `bench eval` times it) on this environment's world: the reference of the
  // Python-loop benchmark (scripts/bench_python.py). Ends any running episode.
  py::dict cpp_episode(int episode, const std::string& agent) {
    DrivingEnv& e = env();
    if (!e.has_suite()) throw ConfigError("cpp_episode: the environment has no suite");
    if (episode < 0 || episode >= e.episodes())
      throw ConfigError("cpp_episode: episode " + std::to_string(episode) + " is out of range");
    e.reset(std::nullopt, episode);  // to end the running episode and fix the task
    World& w = e.mutable_world();
    const Settings& s = e.settings();
    auto a = make_agent(agent, "", s, &w);
    LoopStats stats;
    const EpisodeResult r = run_episode(w, *a, e.task(), s, &stats);
    e.reset(std::nullopt, episode);
    py::dict d;
    d["steps"] = stats.steps;
    d["seconds"] = stats.seconds;
    d["outcome"] = r.outcome;
    return d;
  }

  py::array_t<double> expert_action() {
    if (!env().running()) throw Error("expert_action(): no episode is running (call reset())");
    const Control c = env().expert_action();
    return steers() ? double_array({c.throttle, c.brake, c.steer}) : double_array({c.throttle, c.brake});
  }

 private:
  std::unique_ptr<DrivingEnv> env_;
};

// An Observation from a Python dict (bev (C,H,W) or (K,C,H,W) uint8, speed, command), with the
// frames it points into.
struct ObservationHolder {
  py::array_t<uint8_t, py::array::c_style | py::array::forcecast> frames;
  Observation obs;
};

// Speed and command always; the frames when the agent uses them.
void fill_observation(const py::dict& d, ObservationHolder& h, bool frames) {
  Observation& o = h.obs;
  o.speed = d.contains("speed") ? py::array_t<double, py::array::forcecast>::ensure(d["speed"]).at(0) : 0.0;
  o.command = d.contains("command") ? d["command"].cast<int>() : 0;
  if (!frames) return;
  // The frames under the view's name: "bev", or "camera" (sense.view = "camera").
  const char* key = d.contains("camera") ? "camera" : "bev";
  if (!d.contains(key)) throw ConfigError("the observation has no 'bev' (nor 'camera')");
  h.frames = py::array_t<uint8_t, py::array::c_style | py::array::forcecast>::ensure(d[key]);
  if (!h.frames || (h.frames.ndim() != 3 && h.frames.ndim() != 4))
    throw ConfigError(std::string("observation '") + key +
                      "' must be a uint8 array of shape (C, H, W) or (K, C, H, W)");
  const int nd = static_cast<int>(h.frames.ndim());
  const py::ssize_t k = nd == 4 ? h.frames.shape(0) : 1;
  o.channels = static_cast<int>(h.frames.shape(nd - 3));
  o.height = static_cast<int>(h.frames.shape(nd - 2));
  o.width = static_cast<int>(h.frames.shape(nd - 1));
  o.frames.clear();
  const size_t bytes = static_cast<size_t>(o.channels) * o.height * o.width;
  for (py::ssize_t i = 0; i < k; ++i) o.frames.push_back(h.frames.data() + i * bytes);
}

// A C++ agent called from Python (any agent but the expert, which reads the World).
class PyAgent {
 public:
  PyAgent(const std::string& name, const std::string& checkpoint,
          const std::optional<std::string>& config, const std::optional<py::dict>& settings) {
    if (name == "expert")
      throw ConfigError("the expert drives from the world, not from observations: use "
                        "env.expert_action() or info['expert_action']");
    agent_ = make_agent(name, checkpoint, settings_of(config, settings), nullptr);
    if (agent_->steers_from_world())
      throw ConfigError("agent " + name + " steers a free ego along the route with the expert's "
                        "path tracker, which reads the simulator: it cannot act from observations "
                        "alone (evaluate it with causaldrive.evaluate('" + name +
                        "', ...), or use ego.lateral = \"route\")");
    if (agent_->goal_distance() > 0)
      throw ConfigError("agent " + name + " plans towards a route goal that observations do not "
                        "carry: evaluate it with causaldrive.evaluate('" + name + "', ...)");
  }
  py::array_t<float> act(const py::dict& obs) {
    ObservationHolder h;
    fill_observation(obs, h, agent_->uses_frames());
    const Control c = agent_->act(h.obs);
    return float_array({c.throttle, c.brake, c.steer});
  }
  void reset() { agent_->begin_episode(); }
  const Agent& agent() const { return *agent_; }

 private:
  std::unique_ptr<Agent> agent_;
};

// A Python callable as the benchmark runner's agent: it receives the observation dict (bev of
// shape (C,H,W), or (K,C,H,W) oldest first with history K) and returns (throttle, brake,
// steer) for a free-steering ego, (throttle, brake) (or a steer it ignores) in route mode.
// An object with a reset() method is reset at the start of every episode.
class CallableAgent : public Agent {
 public:
  CallableAgent(py::object policy, std::string label, int history, int stride, bool free)
      : policy_(std::move(policy)),
        label_(std::move(label)),
        history_(history),
        stride_(stride),
        free_(free) {}
  std::string name() const override { return label_; }
  int history() const override { return history_; }
  int history_stride() const override { return stride_; }
  bool steers() const override { return true; }  // it may return (throttle, brake, steer)
  void begin_episode() override {
    if (py::hasattr(policy_, "reset") && !py::isinstance<py::function>(policy_))
      policy_.attr("reset")();
  }
  Control act(const Observation& obs) override {
    const py::ssize_t k = static_cast<py::ssize_t>(obs.frames.size());
    const size_t bytes = static_cast<size_t>(obs.channels) * obs.height * obs.width;
    std::vector<py::ssize_t> shape = {obs.channels, obs.height, obs.width};
    if (history_ > 1) shape.insert(shape.begin(), k);
    py::array_t<uint8_t> frames(shape);
    uint8_t* p = frames.mutable_data();
    for (const uint8_t* f : obs.frames) p = std::copy(f, f + bytes, p);
    py::dict d;
    d[obs.view] = frames;  // "bev" or "camera", as the Python env names it
    d["speed"] = float_array({obs.speed});
    d["command"] = obs.command;
    const std::vector<double> a = action_values(
        policy_(d), free_ ? 3 : 2,
        free_ ? "the policy must return (throttle, brake, steer) for a free-steering ego "
                "(ego.lateral = \"free\")"
              : "the policy must return (throttle, brake) (or a steer, ignored in route mode)",
        3);
    return Control{a[0], a[1], free_ ? a[2] : 0.0};
  }

 private:
  py::object policy_;
  std::string label_;
  int history_, stride_;
  bool free_;
};

py::object evaluate(const py::object& policy, const std::string& suite, const std::string& out,
                    const std::optional<std::string>& label, const std::string& checkpoint,
                    const std::optional<std::string>& config,
                    const std::optional<py::dict>& settings, std::optional<int> trials,
                    int history, int history_stride, bool quiet, bool record) {
  claim_world("evaluate");
  if (out.empty()) throw ConfigError("evaluate: out (the results folder) is required");
  if (history < 1 || history_stride < 1)
    throw ConfigError("evaluate: history and history_stride must be >= 1");
  Settings s = settings_of(config, settings);
  s.eval.suite = suite;
  s.eval.out = out;
  if (trials) {
    if (*trials < 1) throw ConfigError("evaluate: trials must be >= 1");
    s.eval.trials = *trials;
  }
  EvalRequest req;
  req.in_process = true;
  req.quiet = quiet;
  req.record = record;  // eval --record: episodes/episode_NNNNNN.h5 as the agent drove
  if (py::isinstance<py::str>(policy)) {
    req.agent = policy.cast<std::string>();
    req.checkpoint = checkpoint;
    req.label = label.value_or("");
  } else {
    if (!py::hasattr(policy, "__call__"))
      throw ConfigError("evaluate: policy must be a callable or an agent name");
    req.agent = "python";
    req.label = label.value_or("python");
    const std::string name = req.label;
    req.make = [policy, name, history, history_stride](const Settings& st, const World*) {
      return std::make_unique<CallableAgent>(policy, name, history, history_stride,
                                             st.ego.lateral == "free");
    };
  }
  return json_to_python(run_eval(s, req).results);
}

// ---------------------------------------------------------------- MuJoCo-Image

class PyMujocoEnv {
 public:
  PyMujocoEnv(const std::string& name, const std::optional<std::string>& config,
              const std::optional<py::dict>& settings)
      : settings_(settings_of(config, settings)) {
    mj::EnvOptions o;
    o.width = o.height = settings_.mujoco.size;
    env_ = std::make_unique<mj::Env>(name, o);
    limit_ = settings_.mujoco.max_steps > 0 ? std::min(settings_.mujoco.max_steps, env_->max_steps())
                                            : env_->max_steps();
  }

  mj::Env& env() {
    if (!env_) throw Error("the environment is closed");
    return *env_;
  }
  void close() { env_.reset(); expert_.reset(); }

  py::tuple reset(std::optional<uint64_t> seed) {
    seed_ = seed ? *seed : episode_seed(settings_.mujoco.seed, resets_);
    ++resets_;
    py::array_t<uint8_t> frame = frame_array();
    const mj::Frame f = env().reset(seed_);
    std::copy(f.begin(), f.end(), frame.mutable_data());
    expert_.reset();
    running_ = started_ = true;
    ret_ = 0;
    return py::make_tuple(frame, info());
  }

  py::tuple step(const py::handle& action) {
    if (!running_)
      throw Error(started_ ? "step() after the episode ended: call reset() first"
                           : "step() before reset()");
    mj::Env& e = env();
    const std::vector<double> a = action_values(action, e.action_dim(), "one value per actuator");
    const mj::StepResult r = e.step(a);
    const bool truncated = !r.terminated && e.steps() >= limit_;
    ret_ += r.reward;
    running_ = !r.terminated && !truncated;
    py::array_t<uint8_t> frame = frame_array();
    e.render(frame.mutable_data());
    py::dict i = info();
    if (!running_) {
      i["outcome"] = r.terminated ? "terminated" : "truncated";
      i["episode_return"] = ret_;
    }
    return py::make_tuple(frame, r.reward, r.terminated, truncated, i);
  }

  // The expert's action at the current state: collect's expert (the planner, whose query costs
  // samples x horizon env steps, or the trained policy [mujoco] expert_policies names).
  py::array_t<float> expert_action() {
    if (!started_) throw Error("expert_action() before reset()");
    if (!expert_) {
      mj::PlannerOptions p = mj::planner_options(settings_.mujoco);
      p.seed = derive_seed(seed_, 1);  // as collect's expert for an episode of this seed
      expert_ = mj::make_expert(env().name(), p,
                                mj::expert_policies_for(settings_.mujoco.expert_policies,
                                                        env().name(), p));
    }
    const std::vector<double> a = expert_->act(env().state());
    py::array_t<float> out(static_cast<py::ssize_t>(a.size()));
    for (size_t j = 0; j < a.size(); ++j) out.mutable_data()[j] = static_cast<float>(a[j]);
    return out;
  }

  py::dict info() {
    mj::Env& e = env();
    py::dict i;
    const std::vector<double> st = e.state();
    py::array_t<float> state(static_cast<py::ssize_t>(st.size()));
    for (size_t j = 0; j < st.size(); ++j) state.mutable_data()[j] = static_cast<float>(st[j]);
    i["state"] = state;  // privileged: for analysis and experts, never an image policy's input
    i["step"] = e.steps();
    i["seed"] = seed_;
    return i;
  }

  py::array_t<uint8_t> frame_array() {
    mj::Env& e = env();
    return py::array_t<uint8_t>({static_cast<py::ssize_t>(e.channels()),
                                 static_cast<py::ssize_t>(e.height()),
                                 static_cast<py::ssize_t>(e.width())});
  }

  int max_steps() const { return limit_; }

 private:
  Settings settings_;
  std::unique_ptr<mj::Env> env_;
  std::unique_ptr<mj::Expert> expert_;
  int limit_ = 0, resets_ = 0;
  uint64_t seed_ = 0;
  double ret_ = 0;
  bool running_ = false, started_ = false;
};

// ---------------------------------------------------------------- data

py::dict load_episode(const std::string& path) {
  py::dict out, attrs;
  if (read_episode_domain(path) == kMujocoDomain) {
    MujocoEpisode e = read_mujoco_episode(path);
    const auto t = static_cast<py::ssize_t>(e.frames());
    out["obs"] = owning_array<uint8_t>(std::move(e.obs), {t, e.channels, e.height, e.width});
    out["action"] = owning_array<float>(std::move(e.action), {t, e.action_dim});
    out["state"] = owning_array<float>(std::move(e.state), {t, e.state_dim});
    out["reward"] = owning_array<float>(std::move(e.reward), {t});
    out["noise"] = owning_array<uint8_t>(std::move(e.noise), {t});
    attrs["domain"] = kMujocoDomain;
    attrs["format_version"] = e.format_version;
    attrs["env"] = e.env;
    attrs["seed"] = e.seed;
    attrs["dt"] = e.dt;
    attrs["frame_skip"] = e.frame_skip;
    attrs["outcome"] = e.outcome;
    attrs["episode_return"] = e.episode_return;
    for (const auto& [k, v] : e.extra) attrs[k.c_str()] = v;
  } else {
    EpisodeMeta meta;
    EpisodeData d = read_episode(path, &meta);
    const auto t = static_cast<py::ssize_t>(d.frames());
    if (d.camera()) {  // the front camera's RGB frames, as the file's dataset "frames"
      out["frames"] = owning_array<uint8_t>(std::move(d.rgb), {t, d.channels, d.height, d.width});
    } else {
      if (d.bev.empty() && !d.bev_packed.empty()) {
        FrameBytes planes(d.frame_bytes() * d.frames());
        for (size_t i = 0; i < d.frames(); ++i) d.frame_planes(i, planes.data() + i * d.frame_bytes());
        d.bev = std::move(planes);
      }
      out["bev"] = owning_array<uint8_t>(std::move(d.bev), {t, d.channels, d.height, d.width});
    }
    out["speed"] = owning_array<float>(std::move(d.speed), {t});
    out["action"] = owning_array<float>(std::move(d.action), {t, d.action_dim});
    out["command"] = owning_array<int32_t>(std::move(d.command), {t});
    out["pose"] = owning_array<float>(std::move(d.pose), {t, 3});
    if (d.noise.empty()) d.noise.assign(d.frames(), 0);
    out["noise"] = owning_array<uint8_t>(std::move(d.noise), {t});
    // A free-steering ego's lane errors and the lateral augmentation, when the file has them.
    if (!d.lateral_error.empty()) out["lateral_error"] = owning_array<float>(std::move(d.lateral_error), {t});
    if (!d.heading_error.empty()) out["heading_error"] = owning_array<float>(std::move(d.heading_error), {t});
    if (!d.augment.empty()) out["augment"] = owning_array<float>(std::move(d.augment), {t, 2});
    py::dict causes;
    for (auto& [name, series] : d.causes) causes[name.c_str()] = owning_array<float>(std::move(series), {t});
    out["causes"] = causes;
    attrs["domain"] = "driving";
    attrs["format_version"] = meta.format_version;
    attrs["town"] = meta.town;
    attrs["suite"] = meta.suite;
    attrs["seed"] = meta.seed;
    attrs["dt"] = meta.dt;
    attrs["channels"] = meta.channels;
    attrs["metres_per_pixel"] = meta.metres_per_pixel;
    attrs["action_names"] = meta.action_names;
    attrs["outcome"] = meta.outcome;
    for (const auto& [k, v] : meta.extra) attrs[k.c_str()] = v;
  }
  out["attrs"] = attrs;
  return out;
}

}  // namespace

}  // namespace cd::python

PYBIND11_MODULE(_core, m) {
  using namespace cd;
  using namespace cd::python;
  m.doc() = "causaldrive's C++ core (use the causaldrive package, not this module)";
  register_errors(m);

  py::class_<PyDrivingEnv>(m, "DrivingEnv")
      .def(py::init<const std::string&, const std::optional<std::string>&,
                    const std::optional<py::dict>&>(),
           py::arg("name"), py::arg("config") = py::none(), py::arg("settings") = py::none())
      .def("reset", &PyDrivingEnv::reset, py::arg("seed") = py::none(), py::arg("episode") = py::none())
      .def("step", &PyDrivingEnv::step, py::arg("action"))
      .def("expert_action", &PyDrivingEnv::expert_action)
      .def("cpp_episode", &PyDrivingEnv::cpp_episode, py::arg("episode"), py::arg("agent") = "expert")
      .def("close", &PyDrivingEnv::close)
      .def_property_readonly("view", [](PyDrivingEnv& e) { return e.env().world().frame_format().view; })
      .def_property_readonly("channels", [](PyDrivingEnv& e) { return e.env().world().frame_format().channels; })
      .def_property_readonly("height", [](PyDrivingEnv& e) { return e.env().world().frame_format().height; })
      .def_property_readonly("width", [](PyDrivingEnv& e) { return e.env().world().frame_format().width; })
      .def_property_readonly("channel_names", [](PyDrivingEnv& e) { return e.env().world().frame_format().channel_names; })
      .def_property_readonly("episodes", [](PyDrivingEnv& e) { return e.env().episodes(); })
      .def_property_readonly("suite", [](PyDrivingEnv& e) {
        return e.env().has_suite() ? py::object(py::str(e.env().suite().name)) : py::object(py::none());
      })
      .def_property_readonly("town", [](PyDrivingEnv& e) { return e.env().settings().world.town; })
      .def_property_readonly("traffic", [](PyDrivingEnv& e) { return e.env().settings().world.traffic; })
      .def_property_readonly("dt", [](PyDrivingEnv& e) { return e.env().settings().world.dt; })
      .def_property_readonly("cause_names", [](PyDrivingEnv&) { return cause_names(); })
      .def_property_readonly("collision_penalty", [](PyDrivingEnv&) { return kCollisionPenalty; })
      .def_property_readonly("steers", &PyDrivingEnv::steers);

  py::class_<PyMujocoEnv>(m, "MujocoEnv")
      .def(py::init<const std::string&, const std::optional<std::string>&,
                    const std::optional<py::dict>&>(),
           py::arg("name"), py::arg("config") = py::none(), py::arg("settings") = py::none())
      .def("reset", &PyMujocoEnv::reset, py::arg("seed") = py::none())
      .def("step", &PyMujocoEnv::step, py::arg("action"))
      .def("expert_action", &PyMujocoEnv::expert_action)
      .def("close", &PyMujocoEnv::close)
      .def_property_readonly("channels", [](PyMujocoEnv& e) { return e.env().channels(); })
      .def_property_readonly("height", [](PyMujocoEnv& e) { return e.env().height(); })
      .def_property_readonly("width", [](PyMujocoEnv& e) { return e.env().width(); })
      .def_property_readonly("action_low", [](PyMujocoEnv& e) { return e.env().action_low(); })
      .def_property_readonly("action_high", [](PyMujocoEnv& e) { return e.env().action_high(); })
      .def_property_readonly("state_dim", [](PyMujocoEnv& e) { return e.env().state_dim(); })
      .def_property_readonly("max_steps", &PyMujocoEnv::max_steps)
      .def_property_readonly("dt", [](PyMujocoEnv& e) { return e.env().dt(); });

  py::class_<PyAgent>(m, "Agent")
      .def(py::init<const std::string&, const std::string&, const std::optional<std::string>&,
                    const std::optional<py::dict>&>(),
           py::arg("name"), py::arg("checkpoint") = "", py::arg("config") = py::none(),
           py::arg("settings") = py::none())
      .def("act", &PyAgent::act, py::arg("obs"))
      .def("reset", &PyAgent::reset)
      .def("__call__", &PyAgent::act, py::arg("obs"))
      .def_property_readonly("name", [](PyAgent& a) { return a.agent().name(); })
      .def_property_readonly("history", [](PyAgent& a) { return a.agent().history(); })
      .def_property_readonly("history_stride", [](PyAgent& a) { return a.agent().history_stride(); })
      .def_property_readonly("uses_frames", [](PyAgent& a) { return a.agent().uses_frames(); });

  m.def("evaluate", &evaluate, py::arg("policy"), py::arg("suite"), py::arg("out"),
        py::arg("label") = py::none(), py::arg("checkpoint") = "", py::arg("config") = py::none(),
        py::arg("settings") = py::none(), py::arg("trials") = py::none(), py::arg("history") = 1,
        py::arg("history_stride") = 1, py::arg("quiet") = true, py::arg("record") = false);
  m.def("load_episode", &load_episode, py::arg("path"));
  m.def("suite_names", &builtin_suite_names);
  m.def("town_names", &town_names);
  m.def("mujoco_env_names", &mj::env_names);
  m.def("agent_names", [] {
    std::vector<std::string> v;
    for (const MethodSpec& s : methods()) v.push_back(s.name);
    return v;
  });
  m.def("settings_json", [](const std::optional<std::string>& config, const std::optional<py::dict>& over) {
    return json_to_python(settings_to_json(settings_of(config, over)));
  }, py::arg("config") = py::none(), py::arg("settings") = py::none());
}
