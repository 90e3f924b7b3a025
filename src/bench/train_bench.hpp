#pragma once
// `causaldrive bench train`: the training step of a policy network alone, on inputs already on
// the device (random frames, commands and labels, as PyTorch's own benchmarks feed it), for
// comparing devices and the PyTorch-Python peer (scripts/gpu_peer.py builds the same network).
// Data loading is not in it: `causaldrive train` reports its samples/s with the loading.
#include <cstdint>
#include <string>

#include <nlohmann/json.hpp>

namespace cd {

struct TrainBenchOptions {
  std::string method = "bc-oh";    // a method of the policy family
  std::string backbone = "small";  // model.backbone
  std::string device = "auto";     // train.device
  std::string precision = "fp32";  // train.precision
  int frame_channels = 8, history = 4, height = 64, width = 64;  // input: 32 x 64 x 64
  int batch = 128;
  int steps = 50;   // timed steps, after `warmup` untimed ones
  int warmup = 5;
  int threads = 0;  // torch threads (0: torch's default, all cores)
  uint64_t seed = 0;
  // Large CPU tensors on huge pages (device/cpu_memory.hpp): "on", "off", or "both": the timed
  // steps alternate between the two in blocks, and "huge_pages" reports each and their ratio.
  std::string huge_pages = "on";
};

// {"method", "backbone", "device", "precision", "batch", "steps", "parameters",
//  "samples_per_s", "seconds", "first_loss", "runtime",
//  "phases": {"steps", "forward_ms", "backward_ms", "optimizer_ms"}: up to 10 more steps with the
//  device synchronised between the phases, after the timed ones,
//  "huge_pages": "on" | "off" (off when the allocator is not installed: CAUSALDRIVE_HUGE_PAGES=0),
//  or for "both" {"off_samples_per_s", "on_samples_per_s", "ratio": on / off}, and the top
//  "samples_per_s" is on's}
nlohmann::json bench_train_step(const TrainBenchOptions& o);

}  // namespace cd
