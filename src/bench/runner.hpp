#pragma once
// `causaldrive eval`: an agent on every task x trial of a suite, episodes in parallel worker
// processes, one JSON record per finished episode (so a rerun resumes), results.json with
// the summary (SPEC section 5).
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "agents/agent.hpp"
#include "bench/metrics.hpp"
#include "bench/episode_files.hpp"
#include "bench/suite.hpp"
#include "data/episode.hpp"
#include "world/ground_truth.hpp"
#include "world/world.hpp"

namespace cd {

struct EvalRequest {
  std::string agent;       // expert | cs | bc-so | bc-oh ...
  std::string checkpoint;  // for learned agents
  std::string label;       // row name in tables; default: the agent name
  bool quiet = false;
  bool trace = false;      // also write a per-step CSV beside each episode record
  // Also record each episode as the agent drove it, in the HDF5 layout of collect (SPEC
  // section 2), beside its record: the frames the agent saw (the world's BEV for an agent
  // without frames), speed, the agent's controls as `action`, command, pose, causes.
  bool record = false;
  // Set: makes the agent of every episode in place of make_agent(agent, checkpoint) (a Python
  // policy); `agent` and `checkpoint` still name it in run.json.
  std::function<std::unique_ptr<Agent>(const Settings&, const World*)> make;
  // Runs the episodes one after another in this process, without worker processes (an agent
  // that cannot cross a fork: a Python callable). Episodes are reset the same way, so the
  // results are those of the worker processes.
  bool in_process = false;
  // Each episode's loop timed by phase (LoopStats::profile), summed into EvalReport::loop.
  bool profile = false;
};

// Work done by run_episode: agent steps and the wall time of the driving loop (observation,
// agent, simulation step and checks; reset and history prefill excluded).
struct LoopStats {
  long steps = 0;
  double seconds = 0;
  // With `profile` set, where the driving loop's seconds went (bench eval --profile): the
  // agent's sensor (the BEV rendered and pushed into its history), its act() (inference for a
  // learned agent), the world's step (ego model, SUMO, checks) and the scorer.
  bool profile = false;
  double sense_s = 0, act_s = 0, world_s = 0, score_s = 0;
  // Adds another loop's steps and seconds (its phases too), for totals over episodes.
  void add(const LoopStats& o) {
    steps += o.steps;
    seconds += o.seconds;
    sense_s += o.sense_s;
    act_s += o.act_s;
    world_s += o.world_s;
    score_s += o.score_s;
  }
};

struct EvalReport {
  nlohmann::json results;  // what results.json holds
  int run_now = 0;         // episodes run by this call (the rest were already recorded)
  double seconds = 0;
  long steps = 0;          // agent steps run by this call
  // Batched inference (eval.batch): forward passes the inference process ran and the
  // observations in them (0 when the worlds ran their networks themselves).
  long batches = 0, batch_rows = 0;
  double infer_s = 0;
  // The episodes run by this call (this rank's, under MPI): their loops' steps and seconds,
  // and with EvalRequest::profile, the seconds of each phase.
  LoopStats loop;
};


// What an episode's record says of the episode as it runs, for any loop that drives a World:
// made after World::reset (and any prefill), told every step's result, then finished with the
// last one (outcome, collisions, inertia against timeout, stop-go events, light passages).
// What held the ego's path at a step: "free", or the nearest of "leader", "red_light",
// "pedestrian", "yield" within the distance path_free checks; "other" when the path is not free
// and none of them is that near (a gridlock's junction).
std::string path_cause(const GroundTruth& truth);

class EpisodeScorer {
 public:
  EpisodeScorer(const World& world, const Task& task, double dt);
  void observe(const World& world, const StepResult& sr);
  EpisodeResult finish(const World& world, const StepResult& last,
                       nlohmann::json agent_figures = nlohmann::json::object());

 private:
  double dt_, t0_;
  StopGoTracker tracker_;
  std::vector<char> stopped_, free_path_;
  std::vector<float> speed_;
  std::string stop_cause_;  // what held the path when the ego last came to a stop (path_cause)
  EpisodeResult r_;
};

// One episode of `agent` on `task` (with the trial's traffic seed already in it) in `world`:
// holds the ego still for the history prefill, then lets the agent drive until success,
// collision or timeout, and classifies the outcome. With trace_csv, appends one CSV line per
// agent step (time, speed, path free, light state and distance, lead distance, command,
// throttle, brake, target speed). With `record`, fills it with one recorded step per agent
// step (collect/expert_episode.hpp's layout; the agent's controls as the action).
EpisodeResult run_episode(World& world, Agent& agent, const Task& task, const Settings& settings,
                          LoopStats* stats = nullptr, std::string* trace_csv = nullptr,
                          EpisodeData* record = nullptr);


// Runs the suite settings.eval.suite into settings.eval.out (settings.world.town and traffic
// are taken from the suite). Throws ConfigError when the folder holds another run.
EvalReport run_eval(const Settings& settings, const EvalRequest& request);

// What an evaluation folder holds, shared by the driving and the MuJoCo-Image eval: run.json
// (the run's identity) is written when absent; when present, each of `keys` must match, or
// ConfigError (the records would mix). `upgrade` fills keys that older folders lack.
void claim_eval_folder(const std::string& out, const nlohmann::json& run,
                       const std::vector<std::string>& keys,
                       const std::function<void(nlohmann::json&)>& upgrade = {});

// The table printed after a run (Markdown).
std::string results_table(const nlohmann::json& results);

}  // namespace cd
