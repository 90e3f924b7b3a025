#include "bench/runner.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <optional>
#include <sstream>

#include <nlohmann/json.hpp>

#include "device/device.hpp"
#include "core/build_parts.hpp"
#include "agents/observation_feed.hpp"
#include "bench/report.hpp"
#include "collect/expert_episode.hpp"
#include "core/atomic_file.hpp"
#include "core/bitplanes.hpp"
#include "core/error.hpp"
#include "core/fault.hpp"
#include "data/h5_episode.hpp"
#include "core/job.hpp"
#include "core/mpi.hpp"
#include "inference/batched_inference.hpp"
#include "methods/method.hpp"
#include "sense/sensor_shift.hpp"
#include "world/town.hpp"

namespace fs = std::filesystem;

namespace cd {

namespace {

// A finished episode's record, or nothing when it is missing or damaged (run again).
bool load_record(const std::string& path, EpisodeResult* out) {
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) return false;
  try {
    *out = episode_from_json(nlohmann::json::parse(read_file_bytes(path)));
    return true;
  } catch (const std::exception&) {
    return false;
  }
}

// The strengths of a shifted sensor, as results.json records them.
nlohmann::json sensor_shift_json(const EvalSettings& e) {
  const SensorShift& s = e.sensor_shift;
  return {{"seed", s.seed}, {"miss", s.miss}, {"jitter_m", s.jitter_m},
          {"ghosts", s.ghosts}, {"fade", s.fade}};
}

std::string fmt(const char* f, double x) {
  char b[64];
  std::snprintf(b, sizeof b, f, x);
  return b;
}

}  // namespace

EpisodeResult run_episode(World& world, Agent& agent, const Task& task, const Settings& settings,
                          LoopStats* stats, std::string* trace_csv, EpisodeData* record) {
  const double dt = settings.world.dt;
  world.reset(task);
  agent.begin_episode();

  // The agent's sensor (eval.sensor): frames keyed by the trial's traffic seed.
  const SensorShift* shift =
      settings.eval.sensor == "shifted" ? &settings.eval.sensor_shift : nullptr;
  ObservationFeed feed(world, agent, shift, task.traffic_seed);

  StepResult sr;
  // The ego stands (brake held) while real frames fill the history: never one frame repeated.
  const long prefill = std::max<long>(std::lround(settings.eval.prefill_s / dt),
                                      static_cast<long>(feed.span()) - 1);
  for (long i = 0; i < prefill && sr.outcome == Outcome::Running; ++i) {
    feed.push();
    sr = world.step(Control{0.0, 1.0});
  }

  EpisodeScorer scorer(world, task, dt);
  FrameBytes seen;  // the agent's current frame as stored (the BEV packed), for the recording
  if (record) {
    begin_recording(world, *record);
    seen.resize(stored_frame_bytes(world));
  }
  long n = 0;
  const auto wall0 = std::chrono::steady_clock::now();
  const bool profile = stats && stats->profile;
  using Clock = std::chrono::steady_clock;
  Clock::time_point mark;
  // Adds the time since the last lap to `into` (profile only).
  auto lap = [&](double* into) {
    if (!profile) return;
    const Clock::time_point now = Clock::now();
    *into += std::chrono::duration<double>(now - mark).count();
    mark = now;
  };
  double ignored = 0;
  if (profile) mark = Clock::now();
  while (sr.outcome == Outcome::Running) {
    feed.push();
    const Observation& obs = feed.observe();
    lap(profile ? &stats->sense_s : nullptr);
    Control c = agent.act(obs);
    lap(profile ? &stats->act_s : nullptr);
    if (record) {
      if (!obs.frames.empty()) {
        if (world.camera_view())
          std::copy_n(obs.frames.back(), seen.size(), seen.data());
        else
          pack_planes(obs.frames.back(), record->frame_pixels(), record->channels, seen.data());
        record_state(world, *record, seen.data());
      } else {
        record_state(world, *record);
      }
      record_action(*record, c, world.free_lateral());
    }
    if (trace_csv) {
      // A free-steering ego adds its steer, pose (network frame) and lane errors.
      const bool free = world.free_lateral();
      if (trace_csv->empty()) {
        *trace_csv = "time_s,speed,command,throttle,brake,target_speed";
        if (free) *trace_csv += ",steer,x,y,heading,lateral_error_m,heading_error";
        for (const CauseSeries& cs : cause_schema()) *trace_csv += std::string(",") + cs.name;
        *trace_csv += "\n";
      }
      char field[160];
      std::snprintf(field, sizeof field, "%.1f,%.3f,%d,%.3f,%.3f,%.3f", world.time(),
                    world.ego().speed, obs.command, c.throttle, c.brake, agent.last_target_speed());
      *trace_csv += field;
      if (free) {
        const Pose2& p = world.ego().pose;
        const RoadContact& rc = world.road_contact();
        std::snprintf(field, sizeof field, ",%.3f,%.2f,%.2f,%.4f,%.3f,%.4f", c.steer, p.pos.x,
                      p.pos.y, p.heading, rc.lateral_error, rc.heading_error);
        *trace_csv += field;
      }
      for (const CauseSeries& cs : cause_schema()) {
        std::snprintf(field, sizeof field, ",%.6g", cs.value(world.truth()));
        *trace_csv += field;
      }
      *trace_csv += "\n";
    }
    lap(&ignored);  // the recording and the trace
    sr = world.step(c);
    lap(profile ? &stats->world_s : nullptr);
    ++n;
    scorer.observe(world, sr);
    lap(profile ? &stats->score_s : nullptr);
  }
  if (stats) {
    stats->steps += n;
    stats->seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count();
  }
  return scorer.finish(world, sr, agent.episode_figures());
}

EpisodeScorer::EpisodeScorer(const World& world, const Task& task, double dt)
    : dt_(dt), t0_(world.time()), tracker_(dt) {
  r_.scenario = task.scenario;
  r_.traffic_seed = task.traffic_seed;
  r_.route_length_m = task.route_length;
  r_.weather = world.weather();
}

std::string path_cause(const GroundTruth& t) {
  if (t.path_free) return "free";
  const double reach = t.path_free_distance;
  std::string cause = "other";
  double nearest = reach;
  auto consider = [&](bool present, double distance, const char* name) {
    if (present && distance <= nearest) {
      nearest = distance;
      cause = name;
    }
  };
  consider(t.lead_present, t.lead_distance, "leader");
  consider(t.tl_state == kTlRed || t.tl_state == kTlYellow, t.tl_distance, "red_light");
  consider(t.ped_on_path, t.ped_distance, "pedestrian");
  consider(t.must_yield, t.yield_distance, "yield");
  return cause;
}

void EpisodeScorer::observe(const World& world, const StepResult& sr) {
  count_junction_entry(r_, sr.entered_light);
  const double v = world.ego().speed;
  const bool pf = world.truth().path_free;
  tracker_.observe(v, pf);
  const bool stopped = v < kStoppedSpeed;
  // The cause matters only where a standstill begins: read it there, not every step.
  if (stopped && (stopped_.empty() || !stopped_.back())) stop_cause_ = path_cause(world.truth());
  stopped_.push_back(stopped);
  free_path_.push_back(pf);
  speed_.push_back(static_cast<float>(v));
}

EpisodeResult EpisodeScorer::finish(const World& world, const StepResult& last,
                                    nlohmann::json agent_figures) {
  tracker_.finish();
  EpisodeResult r = r_;
  r.events = tracker_.events();
  r.agent = std::move(agent_figures);
  r.duration_s = world.time() - t0_;
  r.distance_m = world.counters().distance;
  switch (last.outcome) {
    case Outcome::Success: r.outcome = "success"; break;
    case Outcome::Collision:
      r.outcome = "collision";
      r.collided_with = last.collided_with;
      r.collision_kind = last.collision_kind;
      r.collision_by = last.ego_struck ? "ego" : "other";
      break;
    case Outcome::Offroad: r.outcome = "offroad"; break;
    default: r.outcome = classify_timeout(stopped_, free_path_, r.events, dt_);
  }
  // What decides the class (SPEC section 14), in the record. Step i ends at (i + 1) dt.
  const size_t n = stopped_.size();
  auto at_step = [&](size_t i) { return std::round(static_cast<double>(i + 1) * dt_ * 1e3) / 1e3; };
  for (size_t i = n; i-- > 1;)
    if (free_path_[i] != free_path_[i - 1]) {
      r.last_free_change_s = at_step(i);
      break;
    }
  if (n > 0 && stopped_.back()) {
    size_t k = n;
    while (k > 0 && stopped_[k - 1]) --k;
    r.last_stop_s = at_step(k);
    r.last_stop_cause = stop_cause_;  // the final standstill began at step k
  }
  const size_t per_second = std::max<size_t>(1, static_cast<size_t>(std::lround(1.0 / dt_)));
  const size_t tail = std::min(n, per_second * static_cast<size_t>(kInertiaSpan));
  for (size_t i = n - tail; i < n; i += per_second) {
    float top = 0;
    for (size_t j = i; j < std::min(n, i + per_second); ++j) top = std::max(top, speed_[j]);
    r.final_max_speed.push_back(std::round(static_cast<double>(top) * 1000.0) / 1000.0);
  }
  r.paper_inertia = last.outcome != Outcome::Success && last.outcome != Outcome::Collision &&
                    last.outcome != Outcome::Offroad && is_paper_inertia(stopped_, dt_);
  const WorldCounters& k = world.counters();
  r.wrong_way = k.wrong_way;
  r.lane_invasions = k.lane_invasions;
  r.lane_changes = k.lane_changes;
  if (k.lateral_samples > 0) r.lateral_error_m = k.lateral_error_sum / k.lateral_samples;
  return r;
}

void claim_eval_folder(const std::string& out, const nlohmann::json& run,
                       const std::vector<std::string>& keys,
                       const std::function<void(nlohmann::json&)>& upgrade) {
  const std::string run_path = out + "/run.json";
  if (!fs::exists(run_path)) {
    write_file_atomic(run_path, run.dump(2) + "\n");
    return;
  }
  nlohmann::json prev;
  try {
    prev = nlohmann::json::parse(read_file_bytes(run_path));
  } catch (const std::exception&) {
    throw DataError(run_path + " is damaged; remove it or use another --out");
  }
  if (upgrade) upgrade(prev);
  for (const std::string& key : keys)
    if (prev.value(key, nlohmann::json()) != run.value(key, nlohmann::json()))
      throw ConfigError(out + " holds another evaluation (" + key + " " +
                        prev.value(key, nlohmann::json()).dump() + ", now " +
                        run.value(key, nlohmann::json()).dump() + "); use another --out");
}

EvalReport run_eval(const Settings& base, const EvalRequest& req) {
  require_sumo("eval of a driving agent");
  // eval.device: its one-line error here, before any worker (which resolves it again); the
  // device the run is on is part of its claim.
  const std::string device = resolve_device(base.eval.device, "eval.device");
  Suite suite = load_suite(base.eval.suite);
  Settings settings = base;
  settings.world.town = suite.town;
  settings.world.traffic = suite.traffic;
  resolve_network(settings.world.town);  // a bad town is one clear error, not one per worker
  // Fails early (bad name, missing or foreign checkpoint) before any worker starts.
  auto new_agent = [&](const World* w) {
    return req.make ? req.make(settings, w) : make_agent(req.agent, req.checkpoint, settings, w);
  };
  std::string agent_name;
  {
    const auto agent = new_agent(nullptr);
    agent_name = agent->name();
    // A run trained on another view or size: one line here rather than one per worker.
    if (!req.make && agent->uses_frames() && !req.checkpoint.empty())
      require_trained_view(req.agent, req.checkpoint, frame_format_of(settings));
  }
  if (settings.eval.sensor == "shifted") require_bev_for_shift(settings.view);
  const int trials = settings.eval.trials > 0 ? settings.eval.trials : suite.trials;
  const int total = static_cast<int>(suite.tasks.size()) * trials;
  const std::string label = req.label.empty() ? req.agent : req.label;

  const std::string& out = settings.eval.out;
  const std::string ep_dir = out + "/episodes";
  // What this folder holds: a rerun must be the same run, or the records would mix.
  nlohmann::json run = {{"agent", req.agent},     {"label", label},
                        {"suite", suite.name},    {"town", suite.town},
                        {"traffic", suite.traffic}, {"trials", trials},
                        {"checkpoint", req.checkpoint}, {"sensor", settings.eval.sensor},
                        {"device", device}};
  if (settings.eval.sensor != "clean") run["sensor_shift"] = sensor_shift_json(settings.eval);
  // The camera's weather: its training pool, or table 8's held-out one (a column of its own).
  if (settings.view == "camera") run["weather"] = settings.camera.weather;

  std::vector<EpisodeResult> results(total);
  EvalReport report;
  report.loop.profile = req.profile;
  // Episode i is trial i % trials of task i / trials.
  auto identify = [&](EpisodeResult& r, int i) {
    r.index = i;
    r.task = i / trials;
    r.trial = i % trials;
  };
  auto task_of = [&](int i) { return suite_episode_task(suite, trials, i); };
  std::unique_ptr<World> world;
  JobSpec spec;
  spec.command = "eval";
  spec.out = out;
  spec.subfolders = {"episodes"};
  // Folders written before eval.sensor existed hold clean runs, and before the device was
  // recorded, CPU runs. Before the camera's weather was recorded (session 46) it cannot be
  // told from the folder: such a folder is taken to be this run's.
  spec.claim = [&] {
    claim_eval_folder(out, run,
                      {"agent", "suite", "trials", "checkpoint", "sensor", "sensor_shift", "device",
                       "inference", "weather"},
                      [&](nlohmann::json& prev) {
                        if (!prev.contains("sensor")) prev["sensor"] = "clean";
                        if (!prev.contains("device")) prev["device"] = "cpu";
                        if (!prev.contains("inference")) prev["inference"] = "batch-1";
                        if (!prev.contains("weather") && run.contains("weather"))
                          prev["weather"] = run["weather"];
                      });
  };
  spec.total = total;
  spec.complete = [&](int i) {
    if (!load_record(ep_dir + "/" + episode_record_name(i), &results[i])) return false;
    // (Every rank reads the same records: every rank stops, rank 0 says it.)
    if (!results[i].has_taxonomy)
      throw_job_error(ep_dir + "/" + episode_record_name(i) +
                      " was evaluated before the failure taxonomy (SPEC section 14): evaluate "
                      "again into a new folder (causaldrive eval ... --out NEW_FOLDER)");
    return true;
  };
  spec.label = "eval " + label + " on " + suite.name;
  spec.quiet = req.quiet;
  spec.workers = settings.eval.workers;
  // A crashed worker or SUMO failure is the infrastructure's fault: run the episode again.
  spec.attempts = settings.eval.max_attempts;
  spec.in_process = req.in_process;
  spec.setup = [&] { world = std::make_unique<World>(settings); };
  spec.run = [&](int i) {
    inject_crash("eval", i, out);  // CAUSALDRIVE_INJECT_CRASH (core/fault.hpp)
    // The agent is made after the fork: each episode starts from the same agent state.
    auto agent = new_agent(world.get());
    LoopStats stats;
    stats.profile = req.profile;
    std::string trace;
    EpisodeData recording;
    const Task task = task_of(i);
    EpisodeResult r = run_episode(*world, *agent, task, settings, &stats,
                                  req.trace ? &trace : nullptr, req.record ? &recording : nullptr);
    if (req.trace) {
      std::string name = episode_record_name(i);
      write_file_atomic(ep_dir + "/" + name.substr(0, name.size() - 5) + ".trace.csv", trace);
    }
    identify(r, i);
    if (req.record) {  // before the episode's record, which commits the episode
      EpisodeMeta meta = recording_meta(*world, settings);
      meta.suite = suite.name;
      meta.seed = task.traffic_seed;
      meta.outcome = r.outcome;
      meta.extra["agent"] = agent_name;
      meta.extra["label"] = label;
      meta.extra["episode_index"] = std::to_string(i);
      meta.extra["task"] = std::to_string(r.task);
      meta.extra["trial"] = std::to_string(r.trial);
      meta.extra["action_source"] = "agent";
      write_episode(ep_dir + "/" + episode_recording_name(i), meta, recording);
    }
    write_file_atomic(ep_dir + "/" + episode_record_name(i), episode_to_json(r).dump() + "\n");
    inject_crash("eval-recorded", i, out, CrashScope::ProcessGroup);
    // The note: steps, outcome, the loop's seconds and (profile) its phases' seconds.
    char timing[160];
    std::snprintf(timing, sizeof timing, " %.9g %.9g %.9g %.9g %.9g", stats.seconds,
                  stats.sense_s, stats.act_s, stats.world_s, stats.score_s);
    return std::to_string(stats.steps) + " " + r.outcome + timing;
  };
  spec.done = [&report](int i, const std::string& note, std::string* line) {
    std::istringstream in(note);
    long steps = 0;
    std::string outcome;
    LoopStats t;
    in >> steps >> outcome >> t.seconds >> t.sense_s >> t.act_s >> t.world_s >> t.score_s;
    t.steps = steps;
    report.loop.add(t);
    *line = "episode " + std::to_string(i) + ": " + outcome;
    return steps;
  };
  // results.json: the folder's commit, by rank 0 while it holds the lock. An episode that still
  // failed is never a policy failure: recorded apart with its own error, run again next time.
  auto write_results = [&](const JobResult& job) {
    const std::vector<int>& remaining = job.pool.failed;
    nlohmann::json episodes = nlohmann::json::array();
    for (int i = 0; i < total; ++i) {
      EpisodeResult& r = results[i];
      const bool failed = std::find(remaining.begin(), remaining.end(), i) != remaining.end();
      if (!failed && std::find(job.todo.begin(), job.todo.end(), i) != job.todo.end() &&
          !load_record(ep_dir + "/" + episode_record_name(i), &r))
        throw DataError("episode record " + episode_record_name(i) + " is missing after its run");
      if (failed) {
        Task t = task_of(i);
        r = EpisodeResult{};
        identify(r, i);
        r.scenario = t.scenario;
        r.traffic_seed = t.traffic_seed;
        r.route_length_m = t.route_length;
        r.outcome = "infrastructure_failure";
        r.failure = job.pool.error_of(i);
      }
      episodes.push_back(episode_to_json(r));
    }
    report.results = run;
    report.results["agent_class"] = agent_name;
    report.results["episodes"] = episodes;
    report.results["summary"] = summarize(results);
    write_file_atomic(out + "/results.json", report.results.dump(2) + "\n");
  };
  // Batched inference (eval.batch): one inference process for this process's worlds.
  const bool policy = !req.make && is_policy_runner_method(req.agent);
  std::optional<InputFormat> input;
  if (policy) input = require_checkpoint(req.checkpoint).input;
  const std::unique_ptr<BatchedInference> inference =
      start_job_inference(spec, settings.eval.batch, device, input ? &*input : nullptr);
  // What the bytes depend on (eval.batch): a folder resumes only with the same.
  run["inference"] = inference_record(inference.get(), device);
  const JobResult job = run_job(spec, write_results);
  report.steps = job.units;
  report.run_now = job.run_now;
  report.seconds = job.seconds;
  if (inference) {
    const BatchStats b = inference->stats();
    report.batches = b.batches;
    report.batch_rows = b.rows;
    report.infer_s = b.infer_s;
  }
  return report;
}

std::string results_table(const nlohmann::json& res) {
  const nlohmann::json& s = res.at("summary");
  auto pct = [&](const char* k) {
    return s.contains(k) ? fmt("%.1f", 100.0 * s.at(k).get<double>()) : std::string("-");
  };
  auto sec = [&](const char* k) {
    return s.at(k).is_null() ? std::string("-") : fmt("%.1f", s.at(k).get<double>());
  };
  // The outcome columns sum to 100 % (SPEC section 14); copycat is three of them.
  std::ostringstream o;
  o << "| agent | suite | episodes | success % | collision % | off-road % | stuck % "
       "| restart stall % | stopped free % | blocked % | slow % | copycat % "
       "| stop-go events | stall % | start delay median / p90 (s) | red lights / km "
       "| green light % | route completion % | mean speed (m/s) |\n";
  o << "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n";
  o << "| " << res.at("label").get<std::string>() << " | "
    << run_column(res.at("suite").get<std::string>(), res.value("sensor", "clean"),
                  res.value("weather", ""))
    << " | " << s.at("episodes").get<long>();
  if (s.at("infrastructure_failures").get<long>() > 0)
    o << " (+" << s.at("infrastructure_failures").get<long>() << " failed)";
  o << " | " << pct("success_rate") << " | " << pct("collision_rate") << " | "
    << pct("offroad_rate") << " | " << pct("stuck_rate") << " | " << pct("restart_stall_rate")
    << " | " << pct("stopped_free_rate") << " | " << pct("blocked_rate") << " | "
    << pct("slow_rate") << " | " << pct("copycat_rate") << " | "
    << s.at("stop_go_events").get<long>() << " | " << pct("stall_rate") << " | "
    << sec("start_delay_median_s") << " / " << sec("start_delay_p90_s") << " | "
    << fmt("%.2f", s.at("red_light_violations_per_km").get<double>()) << " | "
    << (s.at("green_light_rate").is_null() ? std::string("-") : pct("green_light_rate")) << " | "
    << pct("route_completion") << " | " << fmt("%.2f", s.at("mean_speed").get<double>())
    << " |\n";
  return o.str();
}

}  // namespace cd
