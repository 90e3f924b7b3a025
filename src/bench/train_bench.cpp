#include "bench/train_bench.hpp"

#include <algorithm>
#include <chrono>

#include <torch/cuda.h>
#include <torch/torch.h>

#include "app/settings.hpp"
#include "core/error.hpp"
#include "methods/policy_family.hpp"
#include "nn/policy_nets.hpp"
#include "device/cpu_memory.hpp"
#include "device/device.hpp"

namespace cd {

nlohmann::json bench_train_step(const TrainBenchOptions& o) {
  if (o.batch < 1 || o.steps < 1 || o.warmup < 0)
    throw ConfigError("bench train: --batch and --steps must be >= 1, --warmup >= 0");
  if (o.huge_pages != "on" && o.huge_pages != "off" && o.huge_pages != "both")
    throw ConfigError("bench train: --huge-pages is on, off or both, not '" + o.huge_pages + "'");
  const bool allocator = use_huge_pages_for_cpu_tensors();
  if (o.huge_pages == "both" && !allocator)
    throw ConfigError("bench train: --huge-pages both needs the huge-page allocator, which "
                      "CAUSALDRIVE_HUGE_PAGES=0 turned off");
  const bool previous = huge_pages_on();
  set_huge_pages(allocator && o.huge_pages != "off");
  Settings s;
  s.model.backbone = o.backbone;
  s.model.history = o.history;
  if (o.threads > 0) torch::set_num_threads(o.threads);
  const ComputeDevice dev =
      compute_device(o.device, o.precision, false, torch::get_num_threads());
  torch::manual_seed(o.seed);
  const PolicyNetsLayout layout = policy_layout(o.method, s.model, s.residual, s.fca,
                                                o.frame_channels, o.height, o.width, 2, "driving");
  PolicyNets nets(layout);
  if (!nets.policy) throw ConfigError("bench train: method '" + o.method + "' has no policy network");
  nets.to(dev.device);
  nets.set_training(true);
  long parameters = 0;
  for (const torch::Tensor& p : nets.parameters()) parameters += p.numel();
  torch::optim::Adam opt(nets.parameters(), torch::optim::AdamOptions(s.train.lr));

  const int64_t B = o.batch;
  const auto on = torch::TensorOptions().device(dev.device);
  const torch::Tensor image =
      torch::rand({B, static_cast<int64_t>(o.frame_channels) * o.history, o.height, o.width}, on);
  const torch::Tensor speed = torch::zeros({B, 1}, on);
  const torch::Tensor command = torch::randint(0, 4, {B}, on.dtype(torch::kInt64));
  const torch::Tensor target = torch::rand({B, layout.action_dim}, on);
  const torch::Tensor speed_label = torch::rand({B, 1}, on) * 10;

  double first_loss = 0;
  auto forward_loss = [&] {
    AutocastScope autocast(dev);
    PolicyOutput out = nets.policy->forward(image, speed, command, true);
    return policy_loss(s, out, target, speed_label);
  };
  auto step = [&] {
    const torch::Tensor loss = forward_loss();
    opt.zero_grad();
    loss.backward();
    opt.step();
    return loss;
  };
  auto sync = [&] {
    if (dev.name == "cuda") torch::cuda::synchronize();
  };
  for (int i = 0; i < o.warmup; ++i) {
    const torch::Tensor l = step();
    if (i == 0) first_loss = l.item<double>();
  }
  sync();
  torch::Tensor last;
  // The timed steps: `steps` in one block, or for --huge-pages both, blocks of up to 5 steps
  // alternating off and on until each has had `steps`.
  auto timed = [&](int n) {
    sync();
    const auto t0 = std::chrono::steady_clock::now();
    for (int i = 0; i < n; ++i) last = step();
    sync();
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  };
  nlohmann::json huge;
  double seconds = 0;
  if (o.huge_pages == "both") {
    double off = 0;
    for (int done = 0; done < o.steps;) {
      const int n = std::min(5, o.steps - done);
      set_huge_pages(false);
      off += timed(n);
      set_huge_pages(true);
      seconds += timed(n);
      done += n;
    }
    const double per_off = static_cast<double>(o.batch) * o.steps / off,
                 per_on = static_cast<double>(o.batch) * o.steps / seconds;
    huge = {{"off_samples_per_s", per_off}, {"on_samples_per_s", per_on}, {"ratio", per_on / per_off}};
  } else {
    seconds = timed(o.steps);
    huge = huge_pages_on() ? "on" : "off";
  }
  if (o.warmup == 0) first_loss = last.item<double>();

  // Where a step's time goes, from a few more steps with the device synchronised between the
  // phases (so these steps are slower than the timed ones; the peer measures its own the same way).
  const int phase_steps = std::min(o.steps, 10);
  double forward = 0, backward = 0, optimizer = 0;
  auto clock = [&] {
    sync();
    return std::chrono::steady_clock::now();
  };
  auto since = [](std::chrono::steady_clock::time_point a, std::chrono::steady_clock::time_point b) {
    return std::chrono::duration<double, std::milli>(b - a).count();
  };
  for (int i = 0; i < phase_steps; ++i) {
    const auto a = clock();
    const torch::Tensor loss = forward_loss();
    const auto b = clock();
    opt.zero_grad();
    loss.backward();
    const auto c = clock();
    opt.step();
    const auto d = clock();
    forward += since(a, b);
    backward += since(b, c);
    optimizer += since(c, d);
  }
  set_huge_pages(previous);
  const nlohmann::json phases = {{"steps", phase_steps},
                                 {"forward_ms", forward / phase_steps},
                                 {"backward_ms", backward / phase_steps},
                                 {"optimizer_ms", optimizer / phase_steps}};
  return {{"method", o.method},
          {"backbone", o.backbone},
          {"device", dev.name},
          {"precision", dev.precision},
          {"batch", o.batch},
          {"steps", o.steps},
          {"parameters", parameters},
          {"samples_per_s", seconds > 0 ? static_cast<double>(B) * o.steps / seconds : 0.0},
          {"seconds", seconds},
          {"first_loss", first_loss},
          {"runtime", dev.record()},
          {"phases", phases},
          {"huge_pages", huge}};
}

}  // namespace cd
