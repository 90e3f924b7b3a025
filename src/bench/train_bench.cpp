#include "bench/train_bench.hpp"

#include <algorithm>
#include <chrono>

#include <torch/cuda.h>
#include <torch/torch.h>

#include "app/settings.hpp"
#include "core/error.hpp"
#include "methods/policy_family.hpp"
#include "nn/policy_nets.hpp"
#include "device/device.hpp"

namespace cd {

nlohmann::json bench_train_step(const TrainBenchOptions& o) {
  if (o.batch < 1 || o.steps < 1 || o.warmup < 0)
    throw ConfigError("bench train: --batch and --steps must be >= 1, --warmup >= 0");
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
  const auto t0 = std::chrono::steady_clock::now();
  torch::Tensor last;
  for (int i = 0; i < o.steps; ++i) last = step();
  sync();
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
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
          {"phases", phases}};
}

}  // namespace cd
