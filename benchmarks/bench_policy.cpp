// Micro-benchmarks of closed-loop inference: one forward pass of the bc policy network at
// batch 1 on one thread (what each eval worker runs per step), small backbone, both heads.
// Run: build/causaldrive_benchmarks --benchmark_filter=Policy
#include <benchmark/benchmark.h>

#include "nn/policy_net.hpp"

namespace {

void run_policy(benchmark::State& state, int history, const char* head) {
  torch::set_num_threads(1);
  torch::manual_seed(0);
  cd::PolicyNetOptions o;
  o.in_channels = 8 * history;
  o.action_head = head;
  cd::PolicyNet net(o);
  net->eval();
  torch::NoGradGuard no_grad;
  torch::Tensor image = torch::rand({1, o.in_channels, o.height, o.width}).round();
  torch::Tensor speed = torch::zeros({1, 1});
  torch::Tensor command = torch::zeros({1}, torch::kLong);
  for (auto _ : state) {
    auto out = net->forward(image, speed, command, false);
    benchmark::DoNotOptimize(out.action.data_ptr<float>());
  }
}

void BM_PolicyBcSoThrottleBrake(benchmark::State& s) { run_policy(s, 1, "throttle_brake"); }
void BM_PolicyBcOhThrottleBrake(benchmark::State& s) { run_policy(s, 4, "throttle_brake"); }
void BM_PolicyBcOhTargetSpeed(benchmark::State& s) { run_policy(s, 4, "target_speed"); }

}  // namespace

BENCHMARK(BM_PolicyBcSoThrottleBrake)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_PolicyBcOhThrottleBrake)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_PolicyBcOhTargetSpeed)->Unit(benchmark::kMicrosecond);
