#include "datasets/episode_set.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>

#include "core/bitplanes.hpp"
#include "core/error.hpp"
#include "data/h5_episode.hpp"

namespace cd {

namespace fs = std::filesystem;

long EpisodeSet::total_frames() const {
  long n = 0;
  for (const auto& e : episodes) n += e.frames;
  return n;
}

void EpisodeSet::planes01(int e, int t, float* out) const {
  const uint8_t* p = episodes[e].packed.data() + static_cast<size_t>(t) * frame_pixels();
  const size_t n = frame_pixels();
  for (int c = 0; c < channels; ++c) {
    float* plane = out + static_cast<size_t>(c) * n;
    for (size_t i = 0; i < n; ++i) plane[i] = static_cast<float>((p[i] >> c) & 1);
  }
}

void EpisodeSet::planes255(int e, int t, uint8_t* out) const {
  unpack_planes(episodes[e].packed.data() + static_cast<size_t>(t) * frame_pixels(),
                frame_pixels(), channels, out);
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
  if (!d.bev_packed.empty()) {
    p.packed.assign(d.bev_packed.begin(), d.bev_packed.end());
  } else {
    p.packed.assign(static_cast<size_t>(p.frames) * pixels, 0);
    for (int t = 0; t < p.frames; ++t) {
      const uint8_t* frame = d.bev.data() + static_cast<size_t>(t) * d.frame_bytes();
      uint8_t* out = p.packed.data() + static_cast<size_t>(t) * pixels;
      for (int c = 0; c < d.channels; ++c) {
        const uint8_t* plane = frame + static_cast<size_t>(c) * pixels;
        for (size_t i = 0; i < pixels; ++i) out[i] |= static_cast<uint8_t>((plane[i] != 0) << c);
      }
    }
  }
  p.speed = d.speed;
  p.action = d.action;
  p.command = d.command;
  p.pose = d.pose;
  p.causes = d.causes;
  auto it = d.causes.find("path_free");
  if (it != d.causes.end()) p.path_free = it->second;
  return p;
}

}  // namespace

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
  for (const std::string& path : paths) {
    EpisodeMeta meta;
    EpisodeData d;
    try {
      d = read_episode(path, &meta);
    } catch (const Error& e) {
      std::string msg = e.what();
      throw DataError(msg.find(path) != std::string::npos ? msg : path + ": " + msg);
    }
    auto bad = [&](const std::string& why) { throw DataError("episode file " + path + ": " + why); };
    if (d.channels > kMaxPackedChannels)
      bad("has " + std::to_string(d.channels) + " BEV channels; training supports at most " +
          std::to_string(kMaxPackedChannels));
    if (d.action_dim != 2) bad("actions should be (throttle, brake), found " +
                               std::to_string(d.action_dim) + " columns");
    for (float v : d.speed)
      if (!std::isfinite(v)) bad("speed holds a non-finite value");
    for (float v : d.action)
      if (!std::isfinite(v)) bad("action holds a non-finite value");
    if (set.episodes.empty()) {
      set.channels = d.channels;
      set.height = d.height;
      set.width = d.width;
      set.dt = meta.dt;
      set.metres_per_pixel = meta.metres_per_pixel;
      set.channel_names = meta.channels;
    } else if (d.channels != set.channels || d.height != set.height || d.width != set.width) {
      bad("frames are " + std::to_string(d.channels) + "x" + std::to_string(d.height) + "x" +
          std::to_string(d.width) + " but " + set.episodes.front().file + " has " +
          std::to_string(set.channels) + "x" + std::to_string(set.height) + "x" +
          std::to_string(set.width) + "; a data folder must hold one BEV format");
    }
    set.episodes.push_back(pack(path, d));
    if (dirs.size() > 1) set.episodes.back().file = path;  // names repeat across folders
  }
  return set;
}

}  // namespace cd
