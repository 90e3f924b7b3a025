#pragma once
// The episodes of a data folder (the output of `causaldrive collect`) in memory, frames kept
// packed: one byte per pixel, bit c = channel c (core/bitplanes.hpp), 8x smaller than planes.
#include <cstdint>
#include <map>
#include <string>
#include <vector>

namespace cd {

struct PackedEpisode {
  std::string file;              // file name inside the folder
  int frames = 0;                // T
  std::vector<uint8_t> packed;   // T*H*W
  std::vector<float> speed;      // T, m/s
  std::vector<float> action;     // T*A: the expert's label (driving: throttle, brake)
  std::vector<int32_t> command;  // T, cd::Command
  std::vector<float> path_free;  // T, ground truth 0/1; empty when the file has none
  std::vector<float> pose;       // T*3: x, y (m, network frame), heading (rad, 0 = east, CCW)
  // Every ground-truth series of the file's causes/ group (lead_distance, tl_state, ...).
  std::map<std::string, std::vector<float>> causes;
};

struct EpisodeSet {
  std::string dir;
  int channels = 0, height = 0, width = 0;
  double dt = 0.1;                 // s between frames
  double metres_per_pixel = 0.5;
  int action_dim = 2;              // A: components of each recorded action
  std::vector<std::string> channel_names;
  std::vector<PackedEpisode> episodes;  // in file-name order

  size_t frame_pixels() const { return static_cast<size_t>(height) * width; }
  size_t frame_values() const { return static_cast<size_t>(channels) * frame_pixels(); }
  long total_frames() const;
  // Frame t of episode e as C planes of 0/1 floats (network input) or 0/255 bytes (what
  // agents are given); `out` holds frame_values() values.
  void planes01(int e, int t, float* out) const;
  void planes255(int e, int t, uint8_t* out) const;
};

// The episode_*.h5 files of `dir`, sorted, as full paths. Throws DataError when the folder is
// missing or holds no episode file.
std::vector<std::string> list_episode_files(const std::string& dir);

// Reads every episode of `dir`. Throws DataError naming the file for a damaged episode, one
// whose shape or channels differ from the first, one without (throttle, brake) actions, or
// frames with more than 8 channels.
EpisodeSet load_episode_set(const std::string& dir);
// The episodes of several folders in order, as one set (dagger's aggregate); same checks,
// and every folder must hold the same frame format.
EpisodeSet load_episode_set(const std::vector<std::string>& dirs);

}  // namespace cd
