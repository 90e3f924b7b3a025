#include "data/h5_episode.hpp"

#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <limits>
#include <new>
#include <set>
#include <stdexcept>
#include <utility>

#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "data/h5_io.hpp"

namespace cd {
namespace {

using namespace h5;

// Attribute names written by us; EpisodeMeta::extra must not reuse them.
const std::set<std::string>& reserved_attributes() {
  static const std::set<std::string> names = {
      "format_version", "town",     "suite",        "outcome",         "seed", "dt",
      "frames",         "channels", "action_names", "metres_per_pixel"};
  return names;
}

// The bev dataset from packed frames, expanded one frame (one chunk) at a time.
void write_packed_bev(hid_t loc, const EpisodeData& data) {
  const hsize_t t = data.frames(), c = static_cast<hsize_t>(data.channels);
  const hsize_t h = static_cast<hsize_t>(data.height), w = static_cast<hsize_t>(data.width);
  H5Id dcpl = untimed_plist(H5P_DATASET_CREATE);
  const hsize_t chunk[4] = {1, c, h, w};
  check(H5Pset_chunk(dcpl.get(), 4, chunk), "cannot set chunking of 'bev'");
  check(H5Pset_deflate(dcpl.get(), 4), "cannot set compression of 'bev'");
  H5Id space = dataspace({t, c, h, w});
  H5Id dset(check_id(H5Dcreate2(loc, "bev", H5T_STD_U8LE, space.get(), H5P_DEFAULT, dcpl.get(),
                                H5P_DEFAULT),
                     "cannot create dataset 'bev'"),
            H5Dclose);
  H5Id mem = dataspace({1, c, h, w});
  std::vector<uint8_t> planes(data.frame_bytes());
  for (hsize_t i = 0; i < t; ++i) {
    data.frame_planes(i, planes.data());
    const hsize_t start[4] = {i, 0, 0, 0};
    check(H5Sselect_hyperslab(space.get(), H5S_SELECT_SET, start, nullptr, chunk, nullptr),
          "cannot select frame of 'bev'");
    check(H5Dwrite(dset.get(), H5T_NATIVE_UINT8, mem.get(), space.get(), H5P_DEFAULT,
                   planes.data()),
          "cannot write dataset 'bev'");
  }
}

void validate(const EpisodeMeta& meta, const EpisodeData& data) {
  auto bad = [](const std::string& what) { throw DataError("invalid episode: " + what); };
  const size_t frames = data.frames();
  if (frames == 0) bad("speed is empty (an episode needs at least one frame)");
  if (data.channels < 1 || data.height < 1 || data.width < 1) {
    bad("BEV shape " + std::to_string(data.channels) + "x" + std::to_string(data.height) + "x" +
        std::to_string(data.width) + " is not positive");
  }
  if (data.action_dim < 0) bad("action_dim is negative");
  auto expect = [&](const char* field, size_t got, size_t want) {
    if (got != want) {
      bad(std::string(field) + " has " + std::to_string(got) + " values, expected " +
          std::to_string(want) + " for " + std::to_string(frames) + " frames");
    }
  };
  if (!data.rgb_offsets.empty()) bad("frames held as stored (rgb_deflated) are read-only");
  if (data.camera()) {
    if (!data.bev.empty() || !data.bev_packed.empty()) bad("both rgb and bev hold frames");
    if (data.channels != 3) bad("rgb frames have 3 channels, not " + std::to_string(data.channels));
    expect("rgb", data.rgb.size(), frames * data.frame_bytes());
  } else if (data.bev_packed.empty()) {
    expect("bev", data.bev.size(), frames * data.frame_bytes());
  } else {
    if (!data.bev.empty()) bad("both bev and bev_packed hold frames");
    if (data.channels > kMaxPackedChannels)
      bad("bev_packed holds at most " + std::to_string(kMaxPackedChannels) + " channels");
    expect("bev_packed", data.bev_packed.size(), frames * data.frame_pixels());
  }
  expect("action", data.action.size(), frames * static_cast<size_t>(data.action_dim));
  expect("command", data.command.size(), frames);
  expect("pose", data.pose.size(), frames * 3);
  if (!data.noise.empty()) expect("noise", data.noise.size(), frames);
  if (!data.lateral_error.empty()) expect("lateral_error", data.lateral_error.size(), frames);
  if (!data.heading_error.empty()) expect("heading_error", data.heading_error.size(), frames);
  if (!data.augment.empty()) expect("augment", data.augment.size(), frames * 2);
  for (const auto& [name, series] : data.causes) {
    if (name.empty() || name == "." || name.find('/') != std::string::npos) {
      bad("cause name '" + name + "' is not a valid dataset name");
    }
    expect(("causes/" + name).c_str(), series.size(), frames);
  }
  expect("meta.channels", meta.channels.size(), static_cast<size_t>(data.channels));
  expect("meta.action_names", meta.action_names.size(), static_cast<size_t>(data.action_dim));
  for (const auto& [key, value] : meta.extra) {
    if (key.empty() || reserved_attributes().count(key) != 0) {
      bad("meta.extra key '" + key + "' is empty or reserved");
    }
  }
}

void write_file(const std::string& file_path, const EpisodeMeta& meta, const EpisodeData& data) {
  H5Id file = create_file(file_path);
  const hid_t root = file.get();

  write_scalar_attribute<int32_t>(root, "format_version", H5T_STD_I32LE, H5T_NATIVE_INT32,
                                  meta.format_version);
  write_string_attribute(root, "town", meta.town);
  write_string_attribute(root, "suite", meta.suite);
  write_string_attribute(root, "outcome", meta.outcome);
  write_scalar_attribute<uint64_t>(root, "seed", H5T_STD_U64LE, H5T_NATIVE_UINT64, meta.seed);
  write_scalar_attribute<double>(root, "dt", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, meta.dt);
  write_scalar_attribute<double>(root, "metres_per_pixel", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE,
                                 meta.metres_per_pixel);
  write_scalar_attribute<int64_t>(root, "frames", H5T_STD_I64LE, H5T_NATIVE_INT64,
                                  static_cast<int64_t>(data.frames()));
  write_strings_attribute(root, "channels", meta.channels);
  write_strings_attribute(root, "action_names", meta.action_names);
  for (const auto& [key, value] : meta.extra) write_string_attribute(root, key, value);

  const hsize_t t = data.frames();
  const hsize_t c = data.channels, h = data.height, w = data.width;
  const hsize_t a = data.action_dim;
  // One frame per chunk: training reads random frames, each then costs one decompression.
  if (data.camera()) {
    write_dataset(root, "frames", H5T_STD_U8LE, H5T_NATIVE_UINT8, {t, c, h, w}, {1, c, h, w},
                  data.rgb.data());
  } else if (data.bev_packed.empty()) {
    write_dataset(root, "bev", H5T_STD_U8LE, H5T_NATIVE_UINT8, {t, c, h, w}, {1, c, h, w},
                  data.bev.data());
  } else {
    write_packed_bev(root, data);
  }
  write_dataset(root, "speed", H5T_IEEE_F32LE, H5T_NATIVE_FLOAT, {t}, {}, data.speed.data());
  write_dataset(root, "action", H5T_IEEE_F32LE, H5T_NATIVE_FLOAT, {t, a}, {}, data.action.data());
  write_dataset(root, "command", H5T_STD_I32LE, H5T_NATIVE_INT32, {t}, {}, data.command.data());
  write_dataset(root, "pose", H5T_IEEE_F32LE, H5T_NATIVE_FLOAT, {t, 3}, {}, data.pose.data());
  std::vector<uint8_t> clean;
  if (data.noise.empty()) clean.assign(t, 0);
  write_dataset(root, "noise", H5T_STD_U8LE, H5T_NATIVE_UINT8, {t}, {},
                data.noise.empty() ? clean.data() : data.noise.data());
  if (!data.lateral_error.empty())
    write_dataset(root, "lateral_error", H5T_IEEE_F32LE, H5T_NATIVE_FLOAT, {t}, {},
                  data.lateral_error.data());
  if (!data.heading_error.empty())
    write_dataset(root, "heading_error", H5T_IEEE_F32LE, H5T_NATIVE_FLOAT, {t}, {},
                  data.heading_error.data());
  if (!data.augment.empty())
    write_dataset(root, "augment", H5T_IEEE_F32LE, H5T_NATIVE_FLOAT, {t, 2}, {},
                  data.augment.data());

  H5Id gcpl = untimed_plist(H5P_GROUP_CREATE);
  H5Id causes(check_id(H5Gcreate2(root, "causes", H5P_DEFAULT, gcpl.get(), H5P_DEFAULT),
                       "cannot create group 'causes'"),
              H5Gclose);
  for (const auto& [name, series] : data.causes) {
    write_dataset(causes.get(), name, H5T_IEEE_F32LE, H5T_NATIVE_FLOAT, {t}, {}, series.data());
  }
  causes.close();
  check(file.close(), "cannot close " + file_path);
}

EpisodeMeta read_meta(hid_t root) {
  EpisodeMeta meta;
  meta.format_version =
      read_scalar_attribute<int32_t>(root, "format_version", H5T_NATIVE_INT32, H5T_INTEGER);
  if (meta.format_version < 1 || meta.format_version > kEpisodeFormatVersion) {
    throw Failure("unsupported format_version " + std::to_string(meta.format_version));
  }
  meta.town = read_string_attribute(root, "town");
  meta.suite = read_string_attribute(root, "suite");
  meta.outcome = read_string_attribute(root, "outcome");
  meta.seed = read_scalar_attribute<uint64_t>(root, "seed", H5T_NATIVE_UINT64, H5T_INTEGER);
  meta.dt = read_scalar_attribute<double>(root, "dt", H5T_NATIVE_DOUBLE, H5T_FLOAT);
  meta.metres_per_pixel =
      read_scalar_attribute<double>(root, "metres_per_pixel", H5T_NATIVE_DOUBLE, H5T_FLOAT);
  meta.channels = read_strings(root, "channels", false);
  meta.action_names = read_strings(root, "action_names", false);
  for (const std::string& name : attribute_names(root)) {
    if (reserved_attributes().count(name) == 0) {
      meta.extra[name] = read_string_attribute(root, name);
    }
  }
  return meta;
}

// The frames of dataset `name` as stored, one deflate stream per frame, when it is chunked one
// frame per chunk with the deflate filter alone (what write_episode makes); false otherwise,
// with nothing read.
bool read_stored_frames(hid_t root, const char* name, const std::vector<hsize_t>& dims,
                        std::vector<uint8_t>& bytes, std::vector<uint64_t>& offsets) {
  const std::string what = std::string("cannot read the chunks of '") + name + "'";
  H5Id dset(check_id(H5Dopen2(root, name, H5P_DEFAULT), what), H5Dclose);
  H5Id dcpl(check_id(H5Dget_create_plist(dset.get()), what), H5Pclose);
  hsize_t chunk[4] = {0, 0, 0, 0};
  if (H5Pget_layout(dcpl.get()) != H5D_CHUNKED || H5Pget_chunk(dcpl.get(), 4, chunk) != 4 ||
      chunk[0] != 1 || chunk[1] != dims[1] || chunk[2] != dims[2] || chunk[3] != dims[3] ||
      H5Pget_nfilters(dcpl.get()) != 1)
    return false;
  unsigned flags = 0, config = 0;
  size_t values = 0;
  char filter_name[32];
  if (H5Pget_filter2(dcpl.get(), 0, &flags, &values, nullptr, sizeof filter_name, filter_name,
                     &config) != H5Z_FILTER_DEFLATE)
    return false;
  bytes.clear();
  offsets.assign(1, 0);
  for (hsize_t t = 0; t < dims[0]; ++t) {
    const hsize_t at[4] = {t, 0, 0, 0};
    hsize_t size = 0;
    check(H5Dget_chunk_storage_size(dset.get(), at, &size), what);
    const size_t start = bytes.size();
    bytes.resize(start + size);
    uint32_t skipped = 0;  // a bit per filter the chunk was stored without
    check(H5Dread_chunk(dset.get(), H5P_DEFAULT, at, &skipped, bytes.data() + start), what);
    if (skipped != 0) {
      bytes.clear();
      offsets.clear();
      return false;
    }
    offsets.push_back(bytes.size());
  }
  return true;
}

EpisodeData read_data(hid_t root, const EpisodeMeta& meta, bool deflated_camera) {
  EpisodeData data;
  // The frames: the BEV's "bev", or the front camera's "frames" (RGB).
  const bool camera = !has_link(root, "bev", "dataset 'bev'") &&
                      has_link(root, "frames", "dataset 'frames'");
  const char* frames_name = camera ? "frames" : "bev";
  auto bev = read_dataset<uint8_t>(root, frames_name, frames_name, H5T_NATIVE_UINT8, H5T_INTEGER, 4,
                                   !(camera && deflated_camera));
  if (camera && deflated_camera && bev.dims[1] == 3 &&
      !read_stored_frames(root, frames_name, bev.dims, data.rgb_deflated, data.rgb_offsets))
    bev = read_dataset<uint8_t>(root, frames_name, frames_name, H5T_NATIVE_UINT8, H5T_INTEGER, 4);
  if (camera && bev.dims[1] != 3)
    throw Failure("dataset 'frames' should have 3 channels (RGB), has " + std::to_string(bev.dims[1]));
  auto speed = read_dataset<float>(root, "speed", "speed", H5T_NATIVE_FLOAT, H5T_FLOAT, 1);
  auto action = read_dataset<float>(root, "action", "action", H5T_NATIVE_FLOAT, H5T_FLOAT, 2);
  auto command =
      read_dataset<int32_t>(root, "command", "command", H5T_NATIVE_INT32, H5T_INTEGER, 1);
  auto pose = read_dataset<float>(root, "pose", "pose", H5T_NATIVE_FLOAT, H5T_FLOAT, 2);

  const hsize_t frames = speed.dims[0];
  if (frames == 0) throw Failure("episode has no frames");
  auto expect_frames = [&](const std::string& label, hsize_t got) {
    if (got != frames) {
      throw Failure("dataset '" + label + "' has " + std::to_string(got) + " frames, speed has " +
                    std::to_string(frames));
    }
  };
  expect_frames(frames_name, bev.dims[0]);
  expect_frames("action", action.dims[0]);
  expect_frames("command", command.dims[0]);
  expect_frames("pose", pose.dims[0]);
  if (pose.dims[1] != 3) throw Failure("dataset 'pose' should have 3 columns");
  // Optional: files written before the mask existed read as noise-free.
  if (has_link(root, "noise", "dataset 'noise'")) {
    auto noise = read_dataset<uint8_t>(root, "noise", "noise", H5T_NATIVE_UINT8, H5T_INTEGER, 1);
    expect_frames("noise", noise.dims[0]);
    data.noise = std::move(noise.values);
  } else {
    data.noise.assign(frames, 0);
  }
  // Optional: a free-steering ego's lane errors and the lateral augmentation.
  for (auto [name, out] : {std::pair<const char*, std::vector<float>*>{"lateral_error", &data.lateral_error},
                           {"heading_error", &data.heading_error}}) {
    if (!has_link(root, name, std::string("dataset '") + name + "'")) continue;
    auto v = read_dataset<float>(root, name, name, H5T_NATIVE_FLOAT, H5T_FLOAT, 1);
    expect_frames(name, v.dims[0]);
    *out = std::move(v.values);
  }
  if (has_link(root, "augment", "dataset 'augment'")) {
    auto v = read_dataset<float>(root, "augment", "augment", H5T_NATIVE_FLOAT, H5T_FLOAT, 2);
    expect_frames("augment", v.dims[0]);
    if (v.dims[1] != 2) throw Failure("dataset 'augment' should have 2 columns");
    data.augment = std::move(v.values);
  }

  const hsize_t stored_frames = static_cast<hsize_t>(
      read_scalar_attribute<int64_t>(root, "frames", H5T_NATIVE_INT64, H5T_INTEGER));
  if (stored_frames != frames) {
    throw Failure("attribute 'frames' is " + std::to_string(stored_frames) + " but datasets have " +
                  std::to_string(frames));
  }
  if (meta.channels.size() != bev.dims[1]) {
    throw Failure("attribute 'channels' names " + std::to_string(meta.channels.size()) +
                  " channels, " + frames_name + " has " + std::to_string(bev.dims[1]));
  }
  if (meta.action_names.size() != action.dims[1]) {
    throw Failure("attribute 'action_names' names " + std::to_string(meta.action_names.size()) +
                  " actions, action has " + std::to_string(action.dims[1]));
  }

  data.channels = dim_as_int(bev.dims[1], frames_name);
  data.height = dim_as_int(bev.dims[2], frames_name);
  data.width = dim_as_int(bev.dims[3], frames_name);
  data.action_dim = dim_as_int(action.dims[1], "action");
  if (data.rgb_offsets.empty())
    (camera ? data.rgb : data.bev).assign(bev.values.begin(), bev.values.end());
  data.speed = std::move(speed.values);
  data.action = std::move(action.values);
  data.command = std::move(command.values);
  data.pose = std::move(pose.values);

  require_link(root, "causes", "group 'causes'");
  H5Id causes(check_id(H5Gopen2(root, "causes", H5P_DEFAULT), "cannot open group 'causes'"),
              H5Gclose);
  H5G_info_t info;
  check(H5Gget_info(causes.get(), &info), "cannot read group 'causes'");
  for (hsize_t i = 0; i < info.nlinks; ++i) {
    ssize_t length = H5Lget_name_by_idx(causes.get(), ".", H5_INDEX_NAME, H5_ITER_INC, i, nullptr,
                                        0, H5P_DEFAULT);
    if (length < 0) fail("cannot list group 'causes'");
    std::string name(static_cast<size_t>(length) + 1, '\0');
    if (H5Lget_name_by_idx(causes.get(), ".", H5_INDEX_NAME, H5_ITER_INC, i, name.data(),
                           name.size(), H5P_DEFAULT) < 0) {
      fail("cannot list group 'causes'");
    }
    name.resize(static_cast<size_t>(length));
    const std::string label = "causes/" + name;
    auto series = read_dataset<float>(causes.get(), name, label, H5T_NATIVE_FLOAT, H5T_FLOAT, 1);
    expect_frames(label, series.dims[0]);
    data.causes[name] = std::move(series.values);
  }
  return data;
}

}  // namespace

void write_episode(const std::string& path, const EpisodeMeta& meta, const EpisodeData& data) {
  validate(meta, data);
  write_atomically(path, [&](const std::string& tmp) { write_file(tmp, meta, data); });
}

EpisodeData read_episode(const std::string& path, EpisodeMeta* meta, bool deflated_camera) {
  return guarded_read(path, [&] {
    H5Id file = open_for_reading(path);
    EpisodeMeta m = read_meta(file.get());
    EpisodeData data = read_data(file.get(), m, deflated_camera);
    if (meta != nullptr) *meta = std::move(m);
    return data;
  });
}

EpisodeMeta read_episode_meta(const std::string& path) {
  return guarded_read(path, [&] {
    H5Id file = open_for_reading(path);
    return read_meta(file.get());
  });
}

}  // namespace cd
