#pragma once
// HDF5 episode files (SPEC section 2), readable by h5py.
//
// Layout: datasets bev (uint8, T x C x H x W, chunked per frame, deflate; the front camera's
// files hold frames, uint8 T x 3 x H x W RGB, chunked and deflated the same way), speed (float32, T),
// action (float32, T x A), command (int32, T), pose (float32, T x 3), group causes/ with one
// float32 dataset of length T per ground-truth variable. File attributes: format_version,
// town, suite, seed, dt, channels (array of strings), metres_per_pixel, action_names, outcome,
// frames, plus every entry of EpisodeMeta::extra as a string attribute.
// Strings are fixed-length ASCII (h5py returns bytes); the file format is pinned to HDF5 1.8.
// meta.channels must name data.channels channels and meta.action_names the action_dim columns.
// Files are byte-identical for identical input: no timestamps are stored.
#include <string>

#include "data/episode.hpp"

namespace cd {

// Writes atomically: a temporary file in the same folder, fsync, rename. Throws DataError on
// inconsistent input and IoError when the file cannot be written.
void write_episode(const std::string& path, const EpisodeMeta& meta, const EpisodeData& data);

// Reads and validates (shapes, equal first dimensions, format version). Throws DataError on
// a malformed file and IoError on a missing one. With `deflated_camera`, a camera file's frames
// are read as stored (EpisodeData::rgb_deflated: each frame's deflate stream, no decoding) when
// the file keeps one frame per chunk with deflate alone, as ours do; decoded into rgb otherwise.
EpisodeData read_episode(const std::string& path, EpisodeMeta* meta = nullptr,
                         bool deflated_camera = false);

// Reads only the attributes: cheap, used to check that a file is complete when resuming.
EpisodeMeta read_episode_meta(const std::string& path);

}  // namespace cd
