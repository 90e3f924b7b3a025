#pragma once
// MuJoCo-Image episode files (SPEC section 8): the HDF5 layout of section 2 for this domain.
//
// Datasets, all with first dimension T: obs (uint8, T x C x H x W, one chunk per frame,
// deflate), action (float32, T x A, the expert's label), state (float32, T x (nq + nv): qpos then
// qvel before the row's action), reward (float32, T: the reward of the action executed at that
// row), noise (uint8, T: 1 where the executed action was not the label).
// File attributes: format_version, domain ("mujoco": the dataset says its domain), env, seed, dt
// (seconds per step), frame_skip, frames, outcome (terminated | truncated), episode_return, plus
// every entry of `extra` as a string attribute. Same input, same bytes (no timestamps).
#include <cstdint>
#include <map>
#include <string>
#include <vector>

namespace cd {

inline constexpr int kMujocoEpisodeFormatVersion = 1;
inline constexpr const char* kMujocoDomain = "mujoco";

struct MujocoEpisode {
  int format_version = kMujocoEpisodeFormatVersion;
  std::string env;
  uint64_t seed = 0;
  double dt = 0;
  int frame_skip = 1;
  std::string outcome;        // terminated | truncated
  double episode_return = 0;  // sum of reward
  std::map<std::string, std::string> extra;  // expert, noise settings ...

  int channels = 3, height = 0, width = 0;
  int action_dim = 0, state_dim = 0;
  std::vector<uint8_t> obs;    // T*C*H*W
  std::vector<float> action;   // T*action_dim
  std::vector<float> state;    // T*state_dim
  std::vector<float> reward;   // T
  std::vector<uint8_t> noise;  // T

  size_t frames() const { return reward.size(); }
  size_t frame_bytes() const { return static_cast<size_t>(channels) * height * width; }
};

// Writes atomically (temporary file, fsync, rename). Throws DataError on inconsistent input and
// IoError when the file cannot be written.
void write_mujoco_episode(const std::string& path, const MujocoEpisode& episode);

// Reads and validates. Throws IoError on a missing file, DataError on a malformed one (or one of
// another domain).
MujocoEpisode read_mujoco_episode(const std::string& path);

// The file's `domain` attribute, "driving" when it has none (driving files predate it).
// IoError for a missing file, DataError for one HDF5 cannot open.
std::string read_episode_domain(const std::string& path);

// Only the attributes (no datasets): cheap, used to check that a file is complete when resuming.
MujocoEpisode read_mujoco_episode_meta(const std::string& path);

}  // namespace cd
