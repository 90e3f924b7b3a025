#pragma once
// The episodes of a data folder (the output of `causaldrive collect`) in memory, in one of two
// frame layouts behind the same accessors (planes01, planes255):
//   BitPlanes  driving BEV: one byte per pixel, bit c = channel c (core/bitplanes.hpp), 8x
//              smaller than planes; a value is 0 or 1 (0 or 255 as bytes);
//   Bytes      MuJoCo-Image RGB: the frame's C x H x W bytes as recorded; a value is byte / 255.
// The domain says which (the file's `domain` attribute; driving files have none).
#include <cstdint>
#include <map>
#include <string>
#include <vector>

namespace cd {

enum class FrameLayout { BitPlanes, Bytes };

inline constexpr const char* kDrivingDomain = "driving";

// A frame given as C*H*W bytes (planes255) as network input: 0/1 for bit planes (any non-zero
// byte is 1), byte / 255 for RGB bytes. The one conversion of training and inference.
inline void frame_bytes_to_unit(FrameLayout layout, const uint8_t* in, size_t n, float* out) {
  if (layout == FrameLayout::Bytes) {
    for (size_t i = 0; i < n; ++i) out[i] = static_cast<float>(in[i]) / 255.0f;
  } else {
    for (size_t i = 0; i < n; ++i) out[i] = in[i] ? 1.0f : 0.0f;
  }
}

struct PackedEpisode {
  std::string file;              // file name inside the folder
  int frames = 0;                // T
  std::vector<uint8_t> frame_data;  // BitPlanes: T*H*W; Bytes: T*C*H*W, or as stored (below)
  // The camera's frames as stored in the file (data/episode.hpp's rgb_deflated): frame t is the
  // zlib stream frame_data[frame_offsets[t] .. frame_offsets[t + 1]). Empty: frames as above.
  std::vector<uint64_t> frame_offsets;
  std::vector<float> speed;      // T, m/s (MuJoCo: zeros, the domain has no ego speed)
  std::vector<float> action;     // T*A: the expert's label (driving: throttle, brake)
  std::vector<int32_t> command;  // T, cd::Command (MuJoCo: zeros)
  std::vector<float> path_free;  // T, ground truth 0/1; empty when the file has none
  std::vector<float> pose;       // T*3: x, y (m, network frame), heading (rad, 0 = east, CCW)
  // T*2: the lateral augmentation's shift (m, left +) and turn (rad) of the pose each frame was
  // rendered from (0 0: the true pose); empty when the file has none.
  std::vector<float> augment;
  // T: 1 where the executed action was not the expert's (data/episode.hpp); all 0 for files
  // without the mask. Methods whose target is the motion itself leave these steps out.
  std::vector<uint8_t> noise;
  // Every ground-truth series of the file's causes/ group (lead_distance, tl_state, ...).
  std::map<std::string, std::vector<float>> causes;
};

// Whether the motion from step `from` to step `to` (from < to <= T) is the expert's: no step
// from .. to-1 executed a noisy action (the action of step t moves the ego to step t+1). A
// sample whose target is that motion (cim's next speed, dim's future positions, the
// target_speed head) is left out otherwise.
inline bool expert_motion(const PackedEpisode& e, int from, int to) {
  if (e.noise.empty()) return true;
  for (int t = from; t < to; ++t)
    if (e.noise[static_cast<size_t>(t)]) return false;
  return true;
}

struct EpisodeSet {
  std::string dir;
  std::string domain = kDrivingDomain;  // driving | mujoco (data/mujoco_episode.hpp)
  std::string env;                      // MuJoCo: the environment's name; driving: empty
  FrameLayout layout = FrameLayout::BitPlanes;
  int channels = 0, height = 0, width = 0;
  double dt = 0.1;                 // s between frames
  double metres_per_pixel = 0.5;
  int action_dim = 2;              // A: components of each recorded action
  std::vector<std::string> channel_names;
  std::vector<PackedEpisode> episodes;  // in file-name order

  size_t frame_pixels() const { return static_cast<size_t>(height) * width; }
  // Bytes of one stored frame (frame_data holds `frames` of them).
  size_t stored_frame_bytes() const {
    return layout == FrameLayout::Bytes ? frame_values() : frame_pixels();
  }
  size_t frame_values() const { return static_cast<size_t>(channels) * frame_pixels(); }
  long total_frames() const;
  // Frame t of episode e as C planes of floats in [0,1] (network input: 0/1 for bit planes,
  // byte / 255 for RGB) or of bytes (what agents are given: 0/255 for bit planes, the RGB
  // bytes as recorded); `out` holds frame_values() values.
  void planes01(int e, int t, float* out) const;
  void planes255(int e, int t, uint8_t* out) const;
  // Bytes the frames take in memory (camera frames are held as stored in the file: ~2 kB a
  // frame at 288 x 80 where the raw frame is 69 kB).
  size_t frame_memory() const;

 private:
  const uint8_t* stored_frame(int e, int t) const;
};

// The episode_*.h5 files of `dir`, sorted, as full paths. Throws DataError when the folder is
// missing or holds no episode file.
std::vector<std::string> list_episode_files(const std::string& dir);

// Reads every episode of `dir`: driving files (BitPlanes) or MuJoCo-Image files (Bytes, told by
// the file's `domain` attribute). Throws DataError naming the file for a damaged episode, one
// whose shape, channels, domain, env or action size differ from the first, a driving one without
// (throttle, brake) actions, or driving frames with more than 8 channels.
EpisodeSet load_episode_set(const std::string& dir);
// The domain of a data folder from its first episode file's attributes (cheap: no datasets
// read): "mujoco" or "driving". Throws DataError like list_episode_files.
std::string data_domain(const std::string& dir);

// The episodes of several folders in order, as one set (dagger's aggregate); same checks,
// and every folder must hold the same frame format.
EpisodeSet load_episode_set(const std::vector<std::string>& dirs);

}  // namespace cd
