#pragma once
// The driving benchmarks of `causaldrive bench` (world, eval): steps/s measured as
// interleaved ratios in one process (bench/interleaved.hpp), printed as text or one JSON line.
#include <string>
#include <vector>

#include "app/settings.hpp"

namespace cd {

// Bare SUMO stepping against the full loop (ego model, expert, BEV, checks, recording). With
// view "camera", each step of the full loop also builds the front camera's scene and renders it
// (s.camera), and renders the BEV once more, each timed on its own and left out of the loop's
// time: the camera loop's steps/s is then the loop's with the BEV's time replaced by the
// camera's (its scene and its render), the parts all measured in this run.
void bench_world(const Settings& s, long steps, int slices, bool json,
                 const std::string& view = "bev");

// An agent's closed-loop steps/s against the expert's on the first tasks of a suite; with
// `profile`, the microseconds per step of each phase of the loop (LoopStats).
void bench_eval(Settings s, const std::string& agent_name, const std::string& checkpoint,
                const std::string& suite_name, int episodes, bool json, bool profile = false);

// The same at `workers` worlds, as `eval` runs them (worker processes; eval.batch as set):
// the first `episodes` tasks of a suite evaluated `rounds` times, each round the agent, then
// the expert, then (baseline_workers > 0) the agent with eval.batch = "off" at baseline_workers
// workers, today's unbatched evaluation; each into a fresh temporary folder. Steps/s and
// episodes/s (wall time of the whole evaluation, worker start included), the agent's ratio to
// the expert and to the baseline, and the batched inference's mean batch. With `profile`, each
// row's phases as bench_eval's, timed in the world processes.
void bench_eval_workers(Settings s, const std::string& agent_name, const std::string& checkpoint,
                        const std::string& suite_name, int episodes, int workers, int rounds,
                        int baseline_workers, bool json, bool profile = false);

// Inference alone: a learned agent's network on seeded random observations, one row at a time
// (closed loop today) against batches of each size in `slots` (PolicyRunner's fixed slots),
// interleaved round by round; observations/s and the ratio to one row at a time. `threads`:
// torch's intra-op threads (closed loop: 1).
void bench_infer(const std::string& checkpoint, const std::vector<int>& slots, int rounds,
                 int threads, bool json);

}  // namespace cd
