#include "bench/throughput.hpp"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <memory>

#include <nlohmann/json.hpp>

#include "agents/agent.hpp"
#include "app/build_info.hpp"
#include "bench/interleaved.hpp"
#include "bench/runner.hpp"
#include "bench/suite.hpp"
#include "collect/expert_episode.hpp"
#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "core/rng.hpp"
#include "inference/policy_runner.hpp"
#include "methods/method.hpp"
#include "sense/camera.hpp"
#include "world/world.hpp"

namespace cd {

namespace {
using Clock = std::chrono::steady_clock;
}  // namespace

// Steps/s of bare SUMO (the ego driven by SUMO itself) and of the full loop (ego model,
// expert, BEV, checks, recording to memory), interleaved over `slices` tasks: each slice
// runs steps/slices steps of bare SUMO, then as many of the full loop, on the same task.
void bench_world(const Settings& s, long steps, int slices, bool json, const std::string& view) {
  if (view != "bev" && view != "camera")
    throw ConfigError("bench world: --view must be bev or camera, not '" + view + "'");
  World world(s);
  ExpertRecorder recorder(world, s);
  const long per_slice = std::max<long>(1, steps / slices);
  Interleaved m;
  EpisodeData data;
  // The camera's parts, timed apart from the loop (view "camera").
  std::unique_ptr<CameraRenderer> camera;
  if (view == "camera") camera = std::make_unique<CameraRenderer>(world.map(), s.camera);
  std::vector<uint8_t> camera_frame(camera ? camera->frame_bytes() : 0),
      bev_frame(world.renderer().config().height * world.renderer().config().width);
  double scene_s = 0, camera_s = 0, bev_s = 0;
  long camera_steps = 0;
  auto seconds_since = [](Clock::time_point t) {
    return std::chrono::duration<double>(Clock::now() - t).count();
  };
  for (int k = 0; k < slices; ++k) {
    Task task = world.sample_task(episode_seed(s.collect.seed, k), s.collect.min_route_m,
                                  s.collect.max_route_m);
    task.timeout_s = 1e9;  // resets are not what is measured

    world.reset(task);
    world.hand_ego_to_sumo();
    auto t0 = Clock::now();
    for (long i = 0; i < per_slice; ++i) world.step_bare();
    const double bare = std::chrono::duration<double>(Clock::now() - t0).count();

    world.reset(task);
    long done = 0;
    double full = 0;
    while (done < per_slice) {
      // Timed like collection: the episode's buffer, then its steps; resets are not timed.
      auto t1 = Clock::now();
      recorder.begin(data);
      data.bev_packed.reserve(data.frame_pixels() * static_cast<size_t>(per_slice - done));
      StepResult r;
      double apart = 0;  // the camera's parts, not the loop's
      for (; done < per_slice && r.outcome == Outcome::Running; ++done) {
        Control c = recorder.record_step(data);
        if (camera) {
          const auto t2 = Clock::now();
          const CameraScene scene = world.camera_scene();
          const auto t3 = Clock::now();
          camera->render(scene, camera_frame.data());
          const auto t4 = Clock::now();
          world.render_packed(bev_frame.data());
          const double sc = std::chrono::duration<double>(t3 - t2).count(),
                       cam = std::chrono::duration<double>(t4 - t3).count(), bev = seconds_since(t4);
          scene_s += sc, camera_s += cam, bev_s += bev, apart += sc + cam + bev;
          ++camera_steps;
        }
        r = world.step(c);
      }
      full += seconds_since(t1) - apart;
      if (r.outcome != Outcome::Running && done < per_slice) world.reset(task);
    }
    m.add(per_slice, bare, per_slice, full);
  }
  const double sumo_rate = m.steps_a / m.seconds_a, full_rate = m.steps_b / m.seconds_b;
  // Microseconds per step of the camera's parts and of the BEV, and the camera loop's rate.
  const double per = camera_steps > 0 ? 1e6 / static_cast<double>(camera_steps) : 0;
  const double scene_us = scene_s * per, camera_us = camera_s * per, bev_us = bev_s * per;
  const double camera_rate = 1e6 / (1e6 / full_rate - bev_us + scene_us + camera_us);
  if (json) {
    nlohmann::json j = {{"sumo_steps_per_s", sumo_rate},
                        {"full_steps_per_s", full_rate},
                        {"ratio", m.median()}};
    if (camera)
      j["camera"] = {{"width", s.camera.width},          {"height", s.camera.height},
                     {"weather", s.camera.weather},      {"bev_us", bev_us},
                     {"scene_us", scene_us},             {"render_us", camera_us},
                     {"loop_steps_per_s", camera_rate},
                     {"ratio_to_bev_loop", camera_rate / full_rate}};
    j.update(m.spread_json());
    j["build"] = build_components();
    std::printf("%s\n", j.dump().c_str());
  } else {
    std::printf("world %s, %s traffic, %ld steps per loop in %d interleaved slices\n",
                s.world.town.c_str(), s.world.traffic.c_str(), m.steps_a, slices);
    std::printf("  bare SUMO   %10.0f steps/s\n", sumo_rate);
    std::printf("  full loop   %10.0f steps/s\n", full_rate);
    m.print_spread();
    if (camera) {
      std::printf("  camera %dx%d (%s): scene %.0f us, render %.0f us per step; BEV %.0f us\n",
                  s.camera.width, s.camera.height, s.camera.weather.c_str(), scene_us, camera_us,
                  bev_us);
      std::printf("  camera loop %10.0f steps/s, %.2f of the BEV loop's\n", camera_rate,
                  camera_rate / full_rate);
    }
  }
}

// Microseconds per step of each phase of a loop's profile; "other" is the loop's rest
// (recording, bookkeeping).
nlohmann::json phases(const LoopStats& t) {
  const double us = 1e6 / static_cast<double>(std::max<long>(1, t.steps));
  return nlohmann::json{{"sense_us", t.sense_s * us}, {"act_us", t.act_s * us},
                        {"world_us", t.world_s * us}, {"score_us", t.score_s * us},
                        {"other_us", (t.seconds - t.sense_s - t.act_s - t.world_s -
                                      t.score_s) * us},
                        {"step_us", t.seconds * us}};
}

void print_phases_header() {
  std::printf("  us per step    sense      act    world    score    other    total\n");
}
void print_phases(const std::string& name, const LoopStats& t) {
  const nlohmann::json p = phases(t);
  std::printf("  %-10s %8.1f %8.1f %8.1f %8.1f %8.1f %8.1f\n", name.c_str(),
              p["sense_us"].get<double>(), p["act_us"].get<double>(),
              p["world_us"].get<double>(), p["score_us"].get<double>(),
              p["other_us"].get<double>(), p["step_us"].get<double>());
}

// Closed-loop steps/s of an agent (observation history, inference, control, SUMO step,
// checks) on the first tasks of a suite, in this process, interleaved with the expert:
// episode i of the agent, then episode i of the expert on the same task, and so on.
void bench_eval(Settings s, const std::string& agent_name, const std::string& checkpoint,
                const std::string& suite_name, int episodes, bool json, bool profile) {
  Suite suite = load_suite(suite_name);
  s.world.town = suite.town;
  s.world.traffic = suite.traffic;
  World world(s);
  LoopStats agent_total, expert_total;  // the profile, summed over episodes
  auto episode = [&](const std::string& name, const std::string& ckpt, int i) {
    LoopStats stats;
    stats.profile = profile;
    auto agent = make_agent(name, ckpt, s, &world);
    run_episode(world, *agent, suite.tasks[static_cast<size_t>(i) % suite.tasks.size()], s,
                &stats);
    return stats;
  };
  Interleaved m;  // a: the expert, b: the agent
  for (int i = 0; i < episodes; ++i) {
    const LoopStats a = episode(agent_name, checkpoint, i);
    const LoopStats x = episode("expert", "", i);
    m.add(x.steps, x.seconds, a.steps, a.seconds);
    agent_total.add(a);
    expert_total.add(x);
  }
  const double rate = m.steps_b / m.seconds_b, expert_rate = m.steps_a / m.seconds_a;
  if (json) {
    nlohmann::json j = {{"agent", agent_name},       {"suite", suite.name},
                        {"episodes", episodes},      {"steps", m.steps_b},
                        {"steps_per_s", rate},       {"expert_steps_per_s", expert_rate},
                        {"ratio_to_expert", m.median()}};
    j.update(m.spread_json());
    if (profile) j["profile"] = {{"agent", phases(agent_total)}, {"expert", phases(expert_total)}};
    j["build"] = build_components();
    std::printf("%s\n", j.dump().c_str());
  } else {
    std::printf("closed loop on %s, %d episodes per agent, interleaved (one process)\n",
                suite.name.c_str(), episodes);
    std::printf("  %-10s %10.0f steps/s  (%ld steps)\n", agent_name.c_str(), rate, m.steps_b);
    std::printf("  %-10s %10.0f steps/s  (%ld steps)\n", "expert", expert_rate, m.steps_a);
    m.print_spread();
    if (profile) {
      print_phases_header();
      print_phases(agent_name, agent_total);
      print_phases("expert", expert_total);
    }
  }
}

void bench_eval_workers(Settings s, const std::string& agent_name, const std::string& checkpoint,
                        const std::string& suite_name, int episodes, int workers, int rounds,
                        int baseline_workers, bool json, bool profile) {
  if (workers < 1 || rounds < 1 || episodes < 1 || baseline_workers < 0)
    throw ConfigError("bench eval: --workers, --rounds and --episodes must be >= 1");
  Suite suite = load_suite(suite_name);
  if (static_cast<int>(suite.tasks.size()) > episodes) suite.tasks.resize(static_cast<size_t>(episodes));
  suite.trials = 1;
  char tmpl[] = "/tmp/causaldrive-bench-eval-XXXXXX";
  if (!mkdtemp(tmpl)) throw IoError("bench eval: cannot create a temporary folder");
  const std::string tmp = tmpl;
  struct Remove {
    std::string dir;
    ~Remove() {
      std::error_code ec;
      std::filesystem::remove_all(dir, ec);
    }
  } remove{tmp};
  write_file_atomic(tmp + "/suite.json", suite_to_json(suite).dump(2) + "\n");
  s.eval.suite = tmp + "/suite.json";
  s.eval.trials = 1;
  struct Row {
    std::string name, agent, checkpoint, batch;
    int workers;
    long steps = 0, episodes = 0, batches = 0, batch_rows = 0;
    double seconds = 0, infer_s = 0;
    std::vector<double> rates;  // steps/s per round
    LoopStats loop;             // the worlds' loops, summed over the rounds
  };
  std::vector<Row> rows = {{agent_name, agent_name, checkpoint, s.eval.batch, workers},
                           {"expert", "expert", "", s.eval.batch, workers}};
  if (baseline_workers > 0)
    rows.push_back({agent_name + " (batch off)", agent_name, checkpoint, "off", baseline_workers});
  for (int r = 0; r < rounds; ++r)
    for (size_t k = 0; k < rows.size(); ++k) {
      Row& row = rows[k];
      Settings e = s;
      e.eval.workers = row.workers;
      e.eval.batch = row.batch;
      e.eval.out = tmp + "/r" + std::to_string(r) + "-" + std::to_string(k);
      EvalRequest req;
      req.agent = row.agent;
      req.checkpoint = row.checkpoint;
      req.quiet = true;
      req.profile = profile;
      const auto t0 = std::chrono::steady_clock::now();
      const EvalReport rep = run_eval(e, req);
      const double sec = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      row.steps += rep.steps;
      row.episodes += rep.run_now;
      row.seconds += sec;
      row.batches += rep.batches;
      row.batch_rows += rep.batch_rows;
      row.infer_s += rep.infer_s;
      row.loop.add(rep.loop);
      row.rates.push_back(static_cast<double>(rep.steps) / sec);
    }
  auto ratio = [&](size_t a, size_t b) {  // median over rounds of row a's steps/s over row b's
    std::vector<double> q;
    for (int r = 0; r < rounds; ++r) q.push_back(rows[a].rates[r] / rows[b].rates[r]);
    return *quantile(q, 0.5);
  };
  if (json) {
    nlohmann::json j = {{"suite", suite.name}, {"episodes", episodes}, {"rounds", rounds}};
    for (size_t k = 0; k < rows.size(); ++k) {
      const Row& row = rows[k];
      nlohmann::json o = {{"agent", row.agent},  {"workers", row.workers},
                          {"batch", row.batch},  {"steps_per_s", row.steps / row.seconds},
                          {"episodes_per_s", row.episodes / row.seconds}};
      o["batches"] = row.batches;
      if (row.batch_rows > 0) o["infer_us_per_row"] = 1e6 * row.infer_s / row.batch_rows;
      if (profile) o["profile"] = phases(row.loop);
      if (row.batches > 0) o["mean_batch"] = static_cast<double>(row.batch_rows) / row.batches;
      j[k == 0 ? "agent" : k == 1 ? "expert" : "baseline"] = o;
    }
    j["ratio_to_expert"] = ratio(0, 1);
    if (rows.size() > 2) j["speedup_over_baseline"] = ratio(0, 2);
    j["build"] = build_components();
    std::printf("%s\n", j.dump().c_str());
    return;
  }
  std::printf("closed loop on the first %d tasks of %s, %d rounds (agent, expert%s), as eval "
              "runs them\n",
              episodes, suite.name.c_str(), rounds, rows.size() > 2 ? ", baseline" : "");
  for (const Row& row : rows) {
    std::printf("  %-22s workers %2d batch %-3s %9.0f steps/s %7.3f episodes/s", row.name.c_str(),
                row.workers, row.batch.c_str(), row.steps / row.seconds,
                row.episodes / row.seconds);
    if (row.batches > 0)
      std::printf("  (mean batch %.2f, %.0f us of inference per row, busy %.0f%%)",
                  static_cast<double>(row.batch_rows) / row.batches,
                  1e6 * row.infer_s / static_cast<double>(row.batch_rows),
                  100 * row.infer_s / row.seconds);
    std::printf("\n");
  }
  if (profile) {
    // In each world process; a served world's act is its wait for the inference process
    // (the transfer, the queue and its share of the batch), whose own time is shown apart.
    print_phases_header();
    for (const Row& row : rows) {
      print_phases(row.name.substr(0, 10), row.loop);
      if (row.batch_rows > 0)
        std::printf("  %-10s inference process: %.1f us per observation of the %.1f us act\n",
                    "", 1e6 * row.infer_s / static_cast<double>(row.batch_rows),
                    phases(row.loop)["act_us"].get<double>());
    }
  }
  std::printf("  ratio to the expert      %.3f (median of %d rounds)\n", ratio(0, 1), rounds);
  if (rows.size() > 2)
    std::printf("  speed-up over batch off  %.2f (median of %d rounds)\n", ratio(0, 2), rounds);
}

void bench_infer(const std::string& checkpoint, const std::vector<int>& slots, int rounds,
                 int threads, bool json) {
  if (checkpoint.empty()) throw ConfigError("bench infer: give --checkpoint");
  if (slots.empty() || rounds < 1 || threads < 1)
    throw ConfigError("bench infer: --slots, --rounds and --threads must be >= 1");
  for (int s : slots)
    if (s < 1) throw ConfigError("bench infer: every --slots value must be >= 1");
  set_torch_threads(threads);
  PolicyRunner runner(checkpoint);
  const InputFormat& in = runner.checkpoint().input;
  const int most = *std::max_element(slots.begin(), slots.end());
  const size_t values = static_cast<size_t>(in.channels) * in.height * in.width;
  // Seeded observations: driving planes of 0/255, MuJoCo bytes.
  Rng rng(7);
  std::vector<std::vector<uint8_t>> frames(static_cast<size_t>(most) * runner.history(),
                                           std::vector<uint8_t>(values));
  for (auto& f : frames)
    for (uint8_t& b : f)
      b = in.domain == "mujoco" ? static_cast<uint8_t>(rng.uniform(0, 256))
                                : (rng.uniform(0, 1) < 0.2 ? 255 : 0);
  std::vector<std::vector<const uint8_t*>> pointers(static_cast<size_t>(most));
  std::vector<PolicyInput> inputs;
  for (int r = 0; r < most; ++r) {
    for (int k = 0; k < runner.history(); ++k)
      pointers[r].push_back(frames[static_cast<size_t>(r * runner.history() + k)].data());
    inputs.push_back({pointers[r].data(), 5.0, r % 4, nullptr});
  }
  const long per_round = 4L * most;  // observations each loop runs per round
  std::vector<Interleaved> m(slots.size());
  runner.run_batch({inputs.front()});  // warm-up
  for (int round = 0; round < rounds; ++round)
    for (size_t k = 0; k < slots.size(); ++k) {
      runner.set_batch_slots(0);
      auto t0 = Clock::now();
      for (long i = 0; i < per_round; ++i) runner.run_batch({inputs[static_cast<size_t>(i % most)]});
      const double one = std::chrono::duration<double>(Clock::now() - t0).count();
      runner.set_batch_slots(slots[k]);
      const std::vector<PolicyInput> batch(inputs.begin(), inputs.begin() + slots[k]);
      const long passes = per_round / slots[k];
      t0 = Clock::now();
      for (long i = 0; i < passes; ++i) runner.run_batch(batch);
      const double batched = std::chrono::duration<double>(Clock::now() - t0).count();
      m[k].add(per_round, one, passes * slots[k], batched);
    }
  nlohmann::json rows = nlohmann::json::array();
  if (!json)
    std::printf("inference of %s (%s, %d frames of %dx%dx%d), %d thread(s), %d rounds\n",
                checkpoint.c_str(), runner.checkpoint().method.c_str(), runner.history(),
                in.channels, in.height, in.width, threads, rounds);
  for (size_t k = 0; k < slots.size(); ++k) {
    const double one = m[k].steps_a / m[k].seconds_a, batched = m[k].steps_b / m[k].seconds_b;
    if (json) {
      nlohmann::json r = {{"slots", slots[k]}, {"one_per_s", one}, {"batched_per_s", batched},
                          {"ratio", m[k].median()}};
      r.update(m[k].spread_json());
      rows.push_back(r);
    } else {
      std::printf("  one row   %9.0f obs/s (%6.1f us)   %2d slots %9.0f obs/s (%6.1f us)   "
                  "ratio %.2f\n", one, 1e6 / one, slots[k], batched, 1e6 / batched,
                  m[k].median());
    }
  }
  if (json) {
    nlohmann::json j = {{"checkpoint", checkpoint}, {"method", runner.checkpoint().method},
                        {"threads", threads}, {"rounds", rounds}, {"slots", rows}};
    j["build"] = build_components();
    std::printf("%s\n", j.dump().c_str());
  }
}

}  // namespace cd
