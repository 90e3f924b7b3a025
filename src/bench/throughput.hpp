#pragma once
// The driving benchmarks of `causaldrive bench` (world, eval): steps/s measured as
// interleaved ratios in one process (bench/interleaved.hpp), printed as text or one JSON line.
#include <string>

#include "app/settings.hpp"

namespace cd {

// Bare SUMO stepping against the full loop (ego model, expert, BEV, checks, recording).
void bench_world(const Settings& s, long steps, int slices, bool json);

// An agent's closed-loop steps/s against the expert's on the first tasks of a suite.
void bench_eval(Settings s, const std::string& agent_name, const std::string& checkpoint,
                const std::string& suite_name, int episodes, bool json);

}  // namespace cd
