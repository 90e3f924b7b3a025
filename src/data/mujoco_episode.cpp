#include "data/mujoco_episode.hpp"

#include <algorithm>
#include <set>

#include "core/error.hpp"
#include "data/h5_io.hpp"

namespace cd {

namespace {

using namespace h5;

const std::set<std::string>& reserved_attributes() {
  static const std::set<std::string> names = {
      "format_version", "domain", "env",     "seed",          "dt",
      "frame_skip",     "frames", "outcome", "episode_return"};
  return names;
}

void validate(const MujocoEpisode& e) {
  auto bad = [](const std::string& what) { throw DataError("invalid MuJoCo episode: " + what); };
  const size_t t = e.frames();
  if (t == 0) bad("no frames");
  if (e.channels < 1 || e.height < 1 || e.width < 1) bad("frame shape is not positive");
  if (e.action_dim < 1 || e.state_dim < 1) bad("action or state dimension is not positive");
  auto expect = [&](const char* field, size_t got, size_t want) {
    if (got != want) {
      bad(std::string(field) + " has " + std::to_string(got) + " values, expected " +
          std::to_string(want) + " for " + std::to_string(t) + " frames");
    }
  };
  expect("obs", e.obs.size(), t * e.frame_bytes());
  expect("action", e.action.size(), t * e.action_dim);
  expect("state", e.state.size(), t * e.state_dim);
  expect("noise", e.noise.size(), t);
  for (const auto& [key, value] : e.extra)
    if (key.empty() || reserved_attributes().count(key) != 0) bad("extra key '" + key + "' is reserved");
}

void write_file(const std::string& path, const MujocoEpisode& e) {
  H5Id file = create_file(path);
  const hid_t root = file.get();
  write_scalar_attribute<int32_t>(root, "format_version", H5T_STD_I32LE, H5T_NATIVE_INT32,
                                  e.format_version);
  write_string_attribute(root, "domain", kMujocoDomain);
  write_string_attribute(root, "env", e.env);
  write_scalar_attribute<uint64_t>(root, "seed", H5T_STD_U64LE, H5T_NATIVE_UINT64, e.seed);
  write_scalar_attribute<double>(root, "dt", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, e.dt);
  write_scalar_attribute<int32_t>(root, "frame_skip", H5T_STD_I32LE, H5T_NATIVE_INT32,
                                  e.frame_skip);
  write_scalar_attribute<int64_t>(root, "frames", H5T_STD_I64LE, H5T_NATIVE_INT64,
                                  static_cast<int64_t>(e.frames()));
  write_string_attribute(root, "outcome", e.outcome);
  write_scalar_attribute<double>(root, "episode_return", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE,
                                 e.episode_return);
  for (const auto& [key, value] : e.extra) write_string_attribute(root, key, value);

  const hsize_t t = e.frames(), c = e.channels, h = e.height, w = e.width;
  // One frame per chunk: training reads random frames, each then costs one decompression.
  write_dataset(root, "obs", H5T_STD_U8LE, H5T_NATIVE_UINT8, {t, c, h, w}, {1, c, h, w},
                e.obs.data());
  write_dataset(root, "action", H5T_IEEE_F32LE, H5T_NATIVE_FLOAT,
                {t, static_cast<hsize_t>(e.action_dim)}, {}, e.action.data());
  write_dataset(root, "state", H5T_IEEE_F32LE, H5T_NATIVE_FLOAT,
                {t, static_cast<hsize_t>(e.state_dim)}, {}, e.state.data());
  write_dataset(root, "reward", H5T_IEEE_F32LE, H5T_NATIVE_FLOAT, {t}, {}, e.reward.data());
  write_dataset(root, "noise", H5T_STD_U8LE, H5T_NATIVE_UINT8, {t}, {}, e.noise.data());
  check(file.close(), "cannot close " + path);
}

MujocoEpisode read_meta(hid_t root) {
  MujocoEpisode e;
  e.format_version =
      read_scalar_attribute<int32_t>(root, "format_version", H5T_NATIVE_INT32, H5T_INTEGER);
  const std::string domain = read_string_attribute(root, "domain");
  if (domain != kMujocoDomain) throw Failure("domain is '" + domain + "', not 'mujoco'");
  if (e.format_version < 1 || e.format_version > kMujocoEpisodeFormatVersion)
    throw Failure("unsupported format_version " + std::to_string(e.format_version));
  e.env = read_string_attribute(root, "env");
  e.seed = read_scalar_attribute<uint64_t>(root, "seed", H5T_NATIVE_UINT64, H5T_INTEGER);
  e.dt = read_scalar_attribute<double>(root, "dt", H5T_NATIVE_DOUBLE, H5T_FLOAT);
  e.frame_skip = read_scalar_attribute<int32_t>(root, "frame_skip", H5T_NATIVE_INT32, H5T_INTEGER);
  e.outcome = read_string_attribute(root, "outcome");
  e.episode_return =
      read_scalar_attribute<double>(root, "episode_return", H5T_NATIVE_DOUBLE, H5T_FLOAT);
  for (const std::string& name : attribute_names(root))
    if (reserved_attributes().count(name) == 0) e.extra[name] = read_string_attribute(root, name);
  return e;
}

void read_data(hid_t root, MujocoEpisode& e) {
  auto obs = read_dataset<uint8_t>(root, "obs", "obs", H5T_NATIVE_UINT8, H5T_INTEGER, 4);
  auto action = read_dataset<float>(root, "action", "action", H5T_NATIVE_FLOAT, H5T_FLOAT, 2);
  auto state = read_dataset<float>(root, "state", "state", H5T_NATIVE_FLOAT, H5T_FLOAT, 2);
  auto reward = read_dataset<float>(root, "reward", "reward", H5T_NATIVE_FLOAT, H5T_FLOAT, 1);
  auto noise = read_dataset<uint8_t>(root, "noise", "noise", H5T_NATIVE_UINT8, H5T_INTEGER, 1);
  const hsize_t t = reward.dims[0];
  if (t == 0) throw Failure("episode has no frames");
  for (const auto& [label, got] : {std::pair<const char*, hsize_t>{"obs", obs.dims[0]},
                                   {"action", action.dims[0]},
                                   {"state", state.dims[0]},
                                   {"noise", noise.dims[0]}}) {
    if (got != t) {
      throw Failure(std::string("dataset '") + label + "' has " + std::to_string(got) +
                    " frames, reward has " + std::to_string(t));
    }
  }
  const auto stored = static_cast<hsize_t>(
      read_scalar_attribute<int64_t>(root, "frames", H5T_NATIVE_INT64, H5T_INTEGER));
  if (stored != t) throw Failure("attribute 'frames' disagrees with the datasets");
  e.channels = dim_as_int(obs.dims[1], "obs");
  e.height = dim_as_int(obs.dims[2], "obs");
  e.width = dim_as_int(obs.dims[3], "obs");
  e.action_dim = dim_as_int(action.dims[1], "action");
  e.state_dim = dim_as_int(state.dims[1], "state");
  e.obs = std::move(obs.values);
  e.action = std::move(action.values);
  e.state = std::move(state.values);
  e.reward = std::move(reward.values);
  e.noise = std::move(noise.values);
}

}  // namespace

void write_mujoco_episode(const std::string& path, const MujocoEpisode& episode) {
  validate(episode);
  write_atomically(path, [&](const std::string& tmp) { write_file(tmp, episode); });
}

MujocoEpisode read_mujoco_episode(const std::string& path) {
  return guarded_read(path, [&] {
    H5Id file = open_for_reading(path);
    MujocoEpisode e = read_meta(file.get());
    read_data(file.get(), e);
    return e;
  });
}

std::string read_episode_domain(const std::string& path) {
  return guarded_read(path, [&] {
    H5Id file = open_for_reading(path);
    const std::vector<std::string> names = attribute_names(file.get());
    if (std::find(names.begin(), names.end(), "domain") == names.end()) return std::string("driving");
    return read_string_attribute(file.get(), "domain");
  });
}

MujocoEpisode read_mujoco_episode_meta(const std::string& path) {
  return guarded_read(path, [&] {
    H5Id file = open_for_reading(path);
    return read_meta(file.get());
  });
}

}  // namespace cd
