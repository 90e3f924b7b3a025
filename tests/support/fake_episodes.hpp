#pragma once
// Hand-made episode folders for the dataset, method, inference and run tests (no simulator):
// frames whose pixels encode the episode and step, known speeds, actions, commands and path_free.
#include <cstdint>
#include <cstdio>
#include <string>
#include <vector>

#include "test_support.hpp"
#include "data/h5_episode.hpp"

namespace cd::test {

struct FakeEpisodeSpec {
  int frames = 40;
  int channels = 8, height = 32, width = 32;
  bool packed = false;  // store frames as bev_packed (as the recorder does) instead of planes
  // Also the causes the imitation diagnosis reads: a red light 5 m ahead for t % 20 < 5
  // (tl_state 1, else none: 0), a leader 20 m ahead on t % 3 == 0.
  bool situation_causes = false;
};

// Channel 0, row 0: pixel i is on iff bit i of t is set; channel 1, row 0: bits of the episode
// index; the other channels hold a box whose row follows the speed (something to learn).
// speed[t] = 0.25 * (t % 20), so every episode stops at t % 20 == 0 and 1; action =
// (t/1000, episode/100); command = t % 4; path_free = 1 on even t.
inline EpisodeData fake_episode(int episode, const FakeEpisodeSpec& spec) {
  EpisodeData d;
  d.channels = spec.channels;
  d.height = spec.height;
  d.width = spec.width;
  d.action_dim = 2;
  const size_t pixels = static_cast<size_t>(spec.height) * spec.width;
  const size_t fb = spec.channels * pixels;
  std::vector<uint8_t> planes(static_cast<size_t>(spec.frames) * fb, 0);
  for (int t = 0; t < spec.frames; ++t) {
    uint8_t* f = planes.data() + t * fb;
    for (int i = 0; i < 16 && i < spec.width; ++i) {
      if ((t >> i) & 1) f[i] = 255;
      if (spec.channels > 1 && ((episode >> i) & 1)) f[pixels + i] = 255;
    }
    const double speed = 0.25 * (t % 20);
    const int row = 2 + (t % 20) % (spec.height - 4);
    for (int c = 2; c < spec.channels; ++c)
      for (int x = 4; x < 8 && x < spec.width; ++x) f[c * pixels + row * spec.width + x] = 255;
    d.speed.push_back(static_cast<float>(speed));
    d.action.push_back(static_cast<float>(t) / 1000.0f);
    d.action.push_back(static_cast<float>(episode) / 100.0f);
    d.command.push_back(t % 4);
    d.pose.insert(d.pose.end(), {static_cast<float>(t), 0.0f, 0.0f});
    d.causes["path_free"].push_back(t % 2 == 0 ? 1.0f : 0.0f);
    if (spec.situation_causes) {
      const bool red = t % 20 < 5, lead = t % 3 == 0;
      d.causes["tl_state"].push_back(red ? 1.0f : 0.0f);
      d.causes["tl_distance"].push_back(red ? 5.0f : 100.0f);
      d.causes["lead_present"].push_back(lead ? 1.0f : 0.0f);
      d.causes["lead_distance"].push_back(lead ? 20.0f : 100.0f);
    }
  }
  if (spec.packed) {
    d.bev_packed.assign(static_cast<size_t>(spec.frames) * pixels, 0);
    for (int t = 0; t < spec.frames; ++t)
      for (int c = 0; c < spec.channels; ++c)
        for (size_t i = 0; i < pixels; ++i)
          if (planes[t * fb + c * pixels + i]) d.bev_packed[t * pixels + i] |= uint8_t(1u << c);
  } else {
    d.bev.assign(planes.begin(), planes.end());
  }
  return d;
}

inline EpisodeMeta fake_meta(const FakeEpisodeSpec& spec) {
  EpisodeMeta m;
  m.town = "test";
  m.suite = "handmade";
  m.dt = 0.1;
  m.metres_per_pixel = 0.5;
  for (int c = 0; c < spec.channels; ++c) m.channels.push_back("ch" + std::to_string(c));
  m.action_names = {"throttle", "brake"};
  m.outcome = "success";
  return m;
}

inline std::string fake_episode_name(int i) {
  char name[32];
  std::snprintf(name, sizeof name, "episode_%06d.h5", i);
  return name;
}

// Writes `episodes` fake episodes into dir (created).
inline void write_fake_folder(const std::string& dir, int episodes,
                              const FakeEpisodeSpec& spec = {}) {
  fs::create_directories(dir);
  for (int e = 0; e < episodes; ++e)
    write_episode(dir + "/" + fake_episode_name(e), fake_meta(spec), fake_episode(e, spec));
}

// A small, fast training config (1 torch thread, narrow network).
inline std::string learn_config_toml(int epochs = 2, const std::string& extra_model = "",
                                     const std::string& extra_train = "") {
  std::string t;
  t += "[model]\nfeatures = 32\nhistory = 3\nhistory_stride = 2\n" + extra_model;
  t += "\n[train]\nepochs = " + std::to_string(epochs) +
       "\nbatch_size = 16\nval_fraction = 0.25\nthreads = 1\nlr = 1e-3\n" + extra_train;
  return t;
}

}  // namespace cd::test
