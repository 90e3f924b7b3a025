#pragma once
// One recorded episode in memory: the contract of SPEC section 2, independent of HDF5.
#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "core/bitplanes.hpp"
#include "core/frame_buffer.hpp"

namespace cd {

inline constexpr int kEpisodeFormatVersion = 1;

struct EpisodeMeta {
  int format_version = kEpisodeFormatVersion;
  std::string town;
  std::string suite;
  uint64_t seed = 0;
  double dt = 0.1;
  std::vector<std::string> channels;  // BEV channel names, in order
  double metres_per_pixel = 0.5;
  std::vector<std::string> action_names;  // e.g. {"throttle", "brake"}
  std::string outcome;                    // success | collision | timeout | ...
  // Further string attributes (route, traffic level, noise settings ...), written as-is.
  std::map<std::string, std::string> extra;
};

struct EpisodeData {
  int channels = 0, height = 0, width = 0;  // frame shape C x H x W
  int action_dim = 0;
  FrameBytes bev;                // T*C*H*W, row-major, 0 or 255
  // Recorders may fill this instead of bev: T*H*W bytes, bit c of a byte = channel c
  // (see core/bitplanes.hpp). Exactly one of bev and bev_packed holds the frames.
  FrameBytes bev_packed;
  // The front camera's frames (sense.view = "camera"): T*3*H*W RGB bytes, dataset "frames" of
  // the file. When it holds the frames, bev and bev_packed are empty.
  FrameBytes rgb;
  // The same frames as stored in the file, when read so (read_episode's deflated_camera): frame
  // t is the zlib stream rgb_deflated[rgb_offsets[t] .. rgb_offsets[t + 1]) of frame_bytes()
  // bytes; rgb is then empty. What training holds in memory (datasets/episode_set).
  std::vector<uint8_t> rgb_deflated;
  std::vector<uint64_t> rgb_offsets;  // T + 1
  std::vector<float> speed;      // T, m/s
  std::vector<float> action;     // T*action_dim, the expert's action (the label)
  std::vector<int32_t> command;  // T
  std::vector<float> pose;       // T*3: x, y (m, network frame), heading (rad, 0 = east, CCW)
  // T: 1 where the executed action was not the expert's label (noise injection, a DAgger
  // policy), so the motion after that step is not the expert's. Empty is read as all 0 (files
  // written before the dataset existed); recorders always fill it.
  std::vector<uint8_t> noise;
  // A free-steering ego (ego.lateral = "free"), ground truth: T each, the centre's signed offset
  // from its lane's centre line (m, left +) and its heading minus the lane's (rad). Empty in
  // route mode (the datasets are then absent).
  std::vector<float> lateral_error;
  std::vector<float> heading_error;
  // The lateral augmentation (collect.augment): T*2, the shift (m, left +) and rotation (rad) of
  // the pose a frame was rendered from, 0 0 for true frames. Empty when it was off.
  std::vector<float> augment;
  // Ground-truth causes, each a series of length T (group "causes/" in the file).
  std::map<std::string, std::vector<float>> causes;

  size_t frames() const { return speed.size(); }
  bool camera() const { return !rgb.empty() || !rgb_offsets.empty(); }
  size_t frame_bytes() const { return static_cast<size_t>(channels) * height * width; }
  size_t frame_pixels() const { return static_cast<size_t>(height) * width; }
  // Frame t as C planes, whichever representation holds it; out has frame_bytes() bytes.
  void frame_planes(size_t t, uint8_t* out) const;
};

// Inflates one zlib stream of `n` bytes into exactly `out_bytes` bytes at out; DataError naming
// `what` when it is damaged or of another size.
void inflate_frame(const uint8_t* in, size_t n, uint8_t* out, size_t out_bytes,
                   const std::string& what);

}  // namespace cd
