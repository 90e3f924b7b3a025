#include "datasets/episode_set.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>

#include "core/bitplanes.hpp"
#include "core/error.hpp"
#include "data/h5_episode.hpp"
#include "data/mujoco_episode.hpp"

namespace cd {

namespace fs = std::filesystem;

size_t EpisodeSet::frame_memory() const {
  size_t n = 0;
  for (const auto& e : episodes) n += e.frame_data.size() + e.frame_offsets.size() * sizeof(uint64_t);
  return n;
}

long EpisodeSet::total_frames() const {
  long n = 0;
  for (const auto& e : episodes) n += e.frames;
  return n;
}

// Frame t of episode e as stored in memory: a pointer into frame_data, or, for frames held as
// stored in the file, the frame inflated into this thread's buffer.
const uint8_t* EpisodeSet::stored_frame(int e, int t) const {
  const PackedEpisode& ep = episodes[e];
  if (ep.frame_offsets.empty()) return ep.frame_data.data() + static_cast<size_t>(t) * stored_frame_bytes();
  thread_local std::vector<uint8_t> buffer;
  buffer.resize(stored_frame_bytes());
  const uint64_t from = ep.frame_offsets[t], to = ep.frame_offsets[t + 1];
  inflate_frame(ep.frame_data.data() + from, to - from, buffer.data(), buffer.size(),
                ep.file + " frame " + std::to_string(t));
  return buffer.data();
}

void EpisodeSet::planes01(int e, int t, float* out) const {
  const uint8_t* p = stored_frame(e, t);
  if (layout == FrameLayout::Bytes) return frame_bytes_to_unit(layout, p, frame_values(), out);
  const size_t n = frame_pixels();
  for (int c = 0; c < channels; ++c) {
    float* plane = out + static_cast<size_t>(c) * n;
    for (size_t i = 0; i < n; ++i) plane[i] = static_cast<float>((p[i] >> c) & 1);
  }
}

void EpisodeSet::planes255(int e, int t, uint8_t* out) const {
  const uint8_t* p = stored_frame(e, t);
  if (layout == FrameLayout::Bytes) {
    std::copy_n(p, frame_values(), out);
    return;
  }
  unpack_planes(p, frame_pixels(), channels, out);
}

std::vector<std::string> list_episode_files(const std::string& dir) {
  std::error_code ec;
  if (dir.empty() || !fs::is_directory(dir, ec))
    throw DataError("data folder '" + dir +
                    "' not found (record one with `causaldrive collect --out DIR`)");
  std::vector<std::string> files;
  for (const auto& entry : fs::directory_iterator(dir, ec)) {
    const std::string name = entry.path().filename().string();
    if (name.rfind("episode_", 0) == 0 && entry.path().extension() == ".h5" &&
        entry.is_regular_file(ec))
      files.push_back(entry.path().string());
  }
  if (ec) throw DataError("cannot list data folder '" + dir + "': " + ec.message());
  if (files.empty())
    throw DataError("data folder '" + dir +
                    "' holds no episode_*.h5 file (record some with `causaldrive collect`)");
  std::sort(files.begin(), files.end());
  return files;
}

namespace {

PackedEpisode pack(const std::string& path, const EpisodeData& d) {
  PackedEpisode p;
  p.file = fs::path(path).filename().string();
  p.frames = static_cast<int>(d.frames());
  const size_t pixels = d.frame_pixels();
  if (!d.rgb_offsets.empty()) {  // RGB as stored in the file: inflated when read
    p.frame_data = d.rgb_deflated;
    p.frame_offsets = d.rgb_offsets;
  } else if (d.camera()) {
    p.frame_data.assign(d.rgb.begin(), d.rgb.end());  // RGB bytes as recorded (FrameLayout::Bytes)
  } else if (!d.bev_packed.empty()) {
    p.frame_data.assign(d.bev_packed.begin(), d.bev_packed.end());
  } else {
    p.frame_data.assign(static_cast<size_t>(p.frames) * pixels, 0);
    for (int t = 0; t < p.frames; ++t) {
      const uint8_t* frame = d.bev.data() + static_cast<size_t>(t) * d.frame_bytes();
      pack_planes(frame, pixels, d.channels, p.frame_data.data() + static_cast<size_t>(t) * pixels);
    }
  }
  p.speed = d.speed;
  p.action = d.action;
  p.command = d.command;
  p.pose = d.pose;
  p.augment = d.augment;
  p.noise = d.noise.empty() ? std::vector<uint8_t>(d.frames(), 0) : d.noise;
  p.causes = d.causes;
  auto it = d.causes.find("path_free");
  if (it != d.causes.end()) p.path_free = it->second;
  return p;
}

// A MuJoCo-Image episode as stored: RGB bytes, no speed, command 0, no pose or causes.
PackedEpisode keep_bytes(const std::string& path, MujocoEpisode& m) {
  PackedEpisode p;
  p.file = fs::path(path).filename().string();
  p.frames = static_cast<int>(m.frames());
  p.frame_data = std::move(m.obs);
  p.speed.assign(m.frames(), 0.0f);
  p.action = std::move(m.action);
  p.noise = std::move(m.noise);
  p.command.assign(m.frames(), 0);
  return p;
}

// Reads one file of either domain into `set` (the first file fixes the set's format).
void add_episode(EpisodeSet& set, const std::string& path, bool keep_full_path) {
  auto bad = [&](const std::string& why) { throw DataError("episode file " + path + ": " + why); };
  auto rethrow = [&](const Error& e) {
    std::string msg = e.what();
    throw DataError(msg.find(path) != std::string::npos ? msg : path + ": " + msg);
  };
  const bool first = set.episodes.empty();
  std::string domain;
  try {
    domain = read_episode_domain(path);
  } catch (const Error& e) {
    rethrow(e);
  }
  if (!first && domain != set.domain)
    bad("is " + domain + " data but " + set.episodes.front().file + " is " + set.domain +
        "; a data folder must hold one domain");
  int channels = 0, height = 0, width = 0, action_dim = 0;
  PackedEpisode p;
  if (domain == kMujocoDomain) {
    MujocoEpisode m;
    try {
      m = read_mujoco_episode(path);
    } catch (const Error& e) {
      rethrow(e);
    }
    for (float v : m.action)
      if (!std::isfinite(v)) bad("action holds a non-finite value");
    if (first) {
      set.domain = kMujocoDomain;
      set.env = m.env;
      set.layout = FrameLayout::Bytes;
      set.dt = m.dt;
      set.metres_per_pixel = 0;  // not a map
      set.channel_names = {"red", "green", "blue"};
    } else if (m.env != set.env) {
      bad("holds env '" + m.env + "' but " + set.episodes.front().file + " holds '" + set.env +
          "'; a data folder must hold one env");
    }
    channels = m.channels, height = m.height, width = m.width, action_dim = m.action_dim;
    p = keep_bytes(path, m);
  } else {
    EpisodeMeta meta;
    EpisodeData d;
    try {
      d = read_episode(path, &meta, /*deflated_camera=*/true);
    } catch (const Error& e) {
      rethrow(e);
    }
    if (!d.camera() && d.channels > kMaxPackedChannels)
      bad("has " + std::to_string(d.channels) + " BEV channels; training supports at most " +
          std::to_string(kMaxPackedChannels));
    const FrameLayout layout = d.camera() ? FrameLayout::Bytes : FrameLayout::BitPlanes;
    if (!first && layout != set.layout)
      bad(std::string("holds ") + (d.camera() ? "camera" : "BEV") + " frames but " +
          set.episodes.front().file + " holds " + (d.camera() ? "BEV" : "camera") +
          " frames; a data folder must hold one view");
    // (throttle, brake), and steer after them when the ego steered (ego.lateral = "free").
    if (d.action_dim != 2 && d.action_dim != 3)
      bad("actions should be (throttle, brake) or (throttle, brake, steer), found " +
          std::to_string(d.action_dim) + " columns");
    if (d.action_dim == 3 && meta.action_names.size() == 3 && meta.action_names[2] != "steer")
      bad("its third action column is '" + meta.action_names[2] + "', not steer");
    for (float v : d.speed)
      if (!std::isfinite(v)) bad("speed holds a non-finite value");
    for (float v : d.action)
      if (!std::isfinite(v)) bad("action holds a non-finite value");
    if (first) {
      set.dt = meta.dt;
      set.metres_per_pixel = meta.metres_per_pixel;
      set.channel_names = meta.channels;
      set.layout = layout;
    }
    channels = d.channels, height = d.height, width = d.width, action_dim = d.action_dim;
    p = pack(path, d);
  }
  if (first) {
    set.channels = channels;
    set.height = height;
    set.width = width;
    set.action_dim = action_dim;
  } else if (channels != set.channels || height != set.height || width != set.width) {
    bad("frames are " + std::to_string(channels) + "x" + std::to_string(height) + "x" +
        std::to_string(width) + " but " + set.episodes.front().file + " has " +
        std::to_string(set.channels) + "x" + std::to_string(set.height) + "x" +
        std::to_string(set.width) + "; a data folder must hold one frame format");
  } else if (action_dim != set.action_dim) {
    bad("has " + std::to_string(action_dim) + " action components but " +
        set.episodes.front().file + " has " + std::to_string(set.action_dim));
  }
  set.episodes.push_back(std::move(p));
  if (keep_full_path) set.episodes.back().file = path;  // names repeat across folders
}

}  // namespace

std::string data_domain(const std::string& dir) {
  const std::string first = list_episode_files(dir).front();
  try {
    return read_episode_domain(first);
  } catch (const Error& e) {
    std::string msg = e.what();
    throw DataError(msg.find(first) != std::string::npos ? msg : first + ": " + msg);
  }
}

EpisodeSet load_episode_set(const std::string& dir) {
  return load_episode_set(std::vector<std::string>{dir});
}

EpisodeSet load_episode_set(const std::vector<std::string>& dirs) {
  EpisodeSet set;
  std::vector<std::string> paths;
  for (const std::string& dir : dirs) {
    set.dir += (set.dir.empty() ? "" : " + ") + dir;
    for (std::string& p : list_episode_files(dir)) paths.push_back(std::move(p));
  }
  for (const std::string& path : paths) add_episode(set, path, dirs.size() > 1);
  return set;
}

}  // namespace cd
