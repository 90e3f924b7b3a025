// The one table of methods. Adding a method: its file in this folder, and its line here.
#include <algorithm>

#include <filesystem>

#include <nlohmann/json.hpp>

#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "core/run_lock.hpp"
#include "data/mujoco_episode.hpp"
#include "datasets/episode_set.hpp"
#include "inference/policy_runner.hpp"
#include "methods/method.hpp"
#include "sense/camera.hpp"
#include "world/world.hpp"

namespace cd {

// Defined in methods/<name>.cpp.
std::unique_ptr<Agent> load_expert_agent(const std::string&, const std::string&, const Settings&,
                                    const World*);
std::unique_ptr<Agent> load_cs_agent(const std::string&, const std::string&, const Settings&,
                                    const World*);
TrainSummary train_bc(const Settings&, const TrainRequest&);
void bc_so_settings(Settings&);
std::unique_ptr<Agent> load_policy_family_agent(const std::string&, const std::string&,
                                                const Settings&, const World*);
TrainSummary train_residual(const Settings&, const TrainRequest&);
TrainSummary train_fca(const Settings&, const TrainRequest&);
TrainSummary train_keyframe(const Settings&, const TrainRequest&);
TrainSummary train_hd(const Settings&, const TrainRequest&);
TrainSummary train_dagger(const Settings&, const TrainRequest&);
TrainSummary train_dim(const Settings&, const TrainRequest&);
std::unique_ptr<Agent> load_dim_agent(const std::string&, const std::string&, const Settings&,
                                    const World*);
void dim_single_model(Settings&);
TrainSummary train_cim(const Settings&, const TrainRequest&);
std::unique_ptr<Agent> load_cim_agent(const std::string&, const std::string&, const Settings&,
                                    const World*);
void cim_entangled_settings(Settings&);

const std::vector<MethodSpec>& methods() {
  static const std::vector<MethodSpec> table = {
      {"expert", "the privileged autopilot the data was collected with",
       nullptr, load_expert_agent, nullptr, false},
      {"cs", "constant speed along the route, blind (seed 000): the collision upper bound",
       nullptr, load_cs_agent, nullptr, false},
      {"bc-so", "behaviour cloning from the current frame (seed 001)",
       train_bc, load_policy_family_agent, bc_so_settings, false},
      {"bc-oh", "behaviour cloning from a history of frames (seed 001)",
       train_bc, load_policy_family_agent, nullptr, false},
      {"residual", "memory module learns a_t - a_{t-1}, policy acts on the current frame (seed 001)",
       train_residual, load_policy_family_agent, nullptr, false},
      {"fca", "adversary removes the previous action from the history feature (seed 001 baseline)",
       train_fca, load_policy_family_agent, nullptr, false},
      {"keyframe", "loss up-weights samples where the action changes (seed 001 baseline)",
       train_keyframe, load_policy_family_agent, nullptr, false},
      {"hd", "history dropout: past frames blanked with probability hd.p (seed 001 baseline)",
       train_hd, load_policy_family_agent, nullptr, false},
      {"dagger", "bc-oh retrained on closed-loop states labelled by the expert (seed 001 baseline)",
       train_dagger, load_policy_family_agent, nullptr, false},
      {"dim", "imitative trajectory density planned by likelihood (seed 000)",
       train_dim, load_dim_agent, dim_single_model, false},
      {"rip", "ensemble of DIMs on bootstrap resamples, worst-case planning (seed 000)",
       train_dim, load_dim_agent, nullptr, false},
      {"cim", "beta-VAE, Granger causes, causal speed predictor (seed 000)",
       train_cim, load_cim_agent, nullptr, true},
      {"cim-mlp", "cim whose speed predictor sees every latent (seed 000 ablation)",
       train_cim, load_cim_agent, nullptr, true},
      {"cim-entangled", "cim with a plain VAE, beta 1 (seed 000 ablation)",
       train_cim, load_cim_agent, cim_entangled_settings, true},
  };
  return table;
}

namespace {

std::string join(const std::vector<std::string>& names) {
  std::string s;
  for (const auto& n : names) s += (s.empty() ? "" : ", ") + n;
  return s;
}

const MethodSpec* lookup(const std::string& name) {
  for (const MethodSpec& m : methods())
    if (name == m.name) return &m;
  return nullptr;
}

}  // namespace

std::vector<std::string> trainable_methods() {
  std::vector<std::string> names;
  for (const MethodSpec& m : methods())
    if (m.train) names.push_back(m.name);
  return names;
}

const MethodSpec& find_method(const std::string& name) {
  if (const MethodSpec* m = lookup(name)) return *m;
  std::vector<std::string> known;
  for (const MethodSpec& m : methods()) known.push_back(m.name);
  throw ConfigError("unknown agent '" + name + "' (known: " + join(known) + ")");
}

void check_train_method(const std::string& method) {
  const std::vector<std::string> available = trainable_methods();
  if (std::find(available.begin(), available.end(), method) != available.end()) return;
  if (lookup(method))
    throw ConfigError("method '" + method + "' is an agent without training (trainable: " +
                      join(available) + ")");
  throw ConfigError("unknown method '" + method + "' (trainable: " + join(available) + ")");
}

Settings effective_settings(const std::string& method, Settings s) {
  const MethodSpec* m = lookup(method);
  if (m && m->adjust) m->adjust(s);
  return s;
}

TrainSummary train_method(const Settings& settings, const TrainRequest& request) {
  check_train_method(request.method);
  const MethodSpec& m = find_method(request.method);
  if (!m.reuses_runs && (!request.init.empty() || !request.vae_from.empty()))
  {
    std::vector<std::string> reusing;
    for (const MethodSpec& r : methods())
      if (r.reuses_runs) reusing.push_back(r.name);
    throw ConfigError("--init and --vae apply to the cim family only (" + join(reusing) +
                      "), not to '" + request.method + "'");
  }
  // MuJoCo-Image data (the folder's domain) trains the behaviour-cloning family only, and
  // without a speed head: the domain has no ego speed (its speed label and input are zeros).
  std::string domain;
  try {
    domain = data_domain(request.data_dir);
  } catch (const DataError&) {
    // a missing or empty folder: the method reports it in its own order
  }
  // One job per run folder (core/run_lock.hpp); a folder this process holds stays held.
  RunLock lock;
  if (!request.out_dir.empty()) lock = lock_run_folder(request.out_dir, "train");
  if (domain != kMujocoDomain) return m.train(settings, request);
  if (!is_policy_runner_method(request.method))
    throw ConfigError("method '" + request.method + "' trains on driving data only; " +
                      request.data_dir + " is MuJoCo-Image data (bc-so, bc-oh, residual, fca, "
                      "keyframe, hd, dagger train on it)");
  Settings s = settings;
  s.model.speed_loss_weight = 0;
  s.model.speed_input = false;
  return m.train(s, request);
}

namespace {

// What a run's record says its network was trained on: "input" of checkpoint.json (the policy
// family), run.json (the cim family) or dim.json (dim, rip); false when the folder has none
// of them (the method's own loader then says what is missing).
bool trained_frames(const std::string& dir, FrameFormat& out, std::string& record) {
  for (const char* name : {"checkpoint.json", "run.json", "dim.json"}) {
    record = dir + "/" + name;
    if (!std::filesystem::exists(record)) continue;
    try {
      const nlohmann::json in = nlohmann::json::parse(read_file_bytes(record)).at("input");
      out.channels = in.at("channels").get<int>();
      out.height = in.at("height").get<int>();
      out.width = in.at("width").get<int>();
      if (in.contains("channel_names"))
        out.channel_names = in.at("channel_names").get<std::vector<std::string>>();
    } catch (const nlohmann::json::exception&) {
      return false;  // the method's own loader names what is damaged
    }
    out.view = out.channel_names == camera_channel_names() ? "camera" : "bev";
    return true;
  }
  return false;
}

std::string shape_text(const FrameFormat& f) {
  return std::to_string(f.channels) + "x" + std::to_string(f.height) + "x" + std::to_string(f.width);
}

}  // namespace

void require_trained_view(const std::string& agent, const std::string& run_dir,
                          const FrameFormat& world) {
  FrameFormat trained;
  std::string record;
  if (!trained_frames(run_dir, trained, record)) return;
  // The view and the size; the BEV's channel names are not compared (older runs name a few
  // layers otherwise).
  if (trained.view == world.view && trained.channels == world.channels &&
      trained.height == world.height && trained.width == world.width)
    return;
  throw ConfigError("agent '" + agent + "': " + run_dir + " was trained on " + trained.view + " frames (" +
                    shape_text(trained) + "), this world renders " + world.view + " frames (" +
                    shape_text(world) + ", sense.view = \"" + world.view +
                    "\"); evaluate it with the view and size it was trained on");
}

std::unique_ptr<Agent> make_agent(const std::string& name, const std::string& run_dir,
                                  const Settings& settings, const World* world) {
  const MethodSpec& m = find_method(name);
  if (m.train && run_dir.empty())
    throw ConfigError("agent '" + name + "' needs --checkpoint DIR (the output of "
                      "`causaldrive train --method " + name + "`)");
  std::unique_ptr<Agent> agent = m.agent(name, run_dir, settings, world);
  if (world && agent->uses_frames() && !run_dir.empty())
    require_trained_view(name, run_dir, world->frame_format());
  if (settings.ego.lateral == "free" && !agent->steers())
    throw ConfigError("agent '" + name + "' does not steer: it cannot drive with ego.lateral = "
                      "\"free\" yet; use \"route\"");
  return agent;
}

}  // namespace cd
