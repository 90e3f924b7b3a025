#pragma once
// A toy data set for dim / rip (no simulator): straight-line episodes whose frames tell their
// speed class, small settings, in-process training, and what the tests read back from a run
// (its members, an observation and its recorded future).
#include <algorithm>
#include <cmath>
#include <string>
#include <utility>
#include <vector>

#include <torch/torch.h>

#include "app/settings.hpp"
#include "datasets/episode_set.hpp"
#include "datasets/trajectory.hpp"
#include "fake_episodes.hpp"
#include "methods/method.hpp"
#include "nn/dim_net.hpp"
#include "nn/policy_net.hpp"
#include "runs/dim_run.hpp"
#include "train/request.hpp"

namespace cd::test {

inline constexpr int kToyFrames = 60;

// Straight-line episodes in `dir`: episode e drives at speed 2 * (e % 3) m/s with heading 0.4 e, and
// its frames show a box whose row tells that speed class (channels 2..7). Steps
// [noise.first, noise.second) of every episode are marked as noise-injected.
inline void write_toy_folder(const std::string& dir, int episodes,
                             std::pair<int, int> noise = {0, 0}) {
  test::FakeEpisodeSpec spec{.frames = kToyFrames, .channels = 8, .height = 32, .width = 32};
  test::fs::create_directories(dir);
  for (int e = 0; e < episodes; ++e) {
    EpisodeData d = test::fake_episode(e, spec);
    const size_t pixels = 32 * 32, fb = 8 * pixels;
    const double v = 2.0 * (e % 3), h = 0.4 * e;
    d.pose.clear();
    for (int t = 0; t < kToyFrames; ++t) {
      uint8_t* f = d.bev.data() + t * fb;
      std::fill(f + 2 * pixels, f + fb, uint8_t{0});
      const int row = 4 + 10 * (e % 3);
      for (int c = 2; c < 8; ++c)
        for (int y = row; y < row + 6; ++y)
          for (int x = 8; x < 24; ++x) f[c * pixels + y * 32 + x] = 255;
      const double s = v * 0.1 * t;
      d.pose.insert(d.pose.end(), {static_cast<float>(5.0 * e + std::cos(h) * s),
                                   static_cast<float>(-3.0 * e + std::sin(h) * s),
                                   static_cast<float>(h)});
      d.speed[t] = static_cast<float>(v);
    }
    d.noise.assign(kToyFrames, 0);
    for (int t = noise.first; t < noise.second; ++t) d.noise[static_cast<size_t>(t)] = 1;
    write_episode(dir + "/" + test::fake_episode_name(e), test::fake_meta(spec), d);
  }
}

inline Settings toy_settings(int epochs = 4, int ensemble = 3) {
  Settings s;
  s.train.epochs = epochs;
  s.train.batch_size = 16;
  s.train.lr = 3e-3;
  s.train.threads = 1;
  s.train.device = "cpu";  // same bytes are the CPU's (a GPU machine would resolve auto to CUDA)
  s.train.val_fraction = 0.25;
  s.train.seed = 7;
  s.dim.features = 16;
  s.dim.hidden = 32;
  s.dim.ensemble = ensemble;
  return s;
}

inline TrainSummary train_toy(const Settings& s, const std::string& method, const std::string& data,
                   const std::string& out) {
  TrainRequest r;
  r.method = method;
  r.data_dir = data;
  r.out_dir = out;
  r.quiet = true;
  return train_method(s, r);
}

// The members of a finished run folder, as the planner builds them.
inline std::vector<DimNet> load_members(const std::string& dir) {
  DimRun run = *read_dim_run(dir);
  DimNetOptions o;
  o.channels = run.input.channels;
  o.height = run.input.height;
  o.width = run.input.width;
  o.horizon = run.dim.horizon;
  o.past = run.dim.past;
  o.features = run.dim.features;
  o.hidden = run.dim.hidden;
  o.min_std = run.dim.min_std;
  std::vector<DimNet> nets;
  for (int k = 0; k < static_cast<int>(run.members.size()); ++k) {
    DimNet net(o);
    const std::string p = dir + "/" + dim_member_file(k);
    load_module_bytes(*net, test::read_text(p), torch::kCPU, p);
    nets.push_back(net);
  }
  return nets;
}

// Frame t of episode e of a folder as a 1 x C x H x W tensor, and its past positions.
struct ToyObservation {
  torch::Tensor frame, past, future;
};
inline ToyObservation toy_observation(const std::string& data, int e, int t, const DimSettings& d) {
  EpisodeSet set = load_episode_set(data);
  ToyObservation o;
  o.frame = torch::empty({1, set.channels, set.height, set.width});
  set.planes01(e, t, o.frame.data_ptr<float>());
  o.past = torch::empty({1, d.past, 2});
  o.future = torch::empty({1, d.horizon, 2});
  dim_sample_positions(set.episodes[e], t, d, o.past.data_ptr<float>(),
                       o.future.data_ptr<float>());
  return o;
}

}  // namespace cd::test
