#include "data/h5_episode.hpp"

#include <hdf5.h>
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

namespace cd {
namespace {

// Raised by the helpers below; the public functions turn it into IoError or DataError with the
// file's path, so each helper only has to say what went wrong.
struct Failure : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// Attribute names written by us; EpisodeMeta::extra must not reuse them.
const std::set<std::string>& reserved_attributes() {
  static const std::set<std::string> names = {
      "format_version", "town",     "suite",        "outcome",         "seed", "dt",
      "frames",         "channels", "action_names", "metres_per_pixel"};
  return names;
}

// Owns one HDF5 identifier and closes it with the matching H5*close function, so that nothing
// leaks (and no file stays open) when an exception unwinds.
class H5Id {
 public:
  using Closer = herr_t (*)(hid_t);
  H5Id(hid_t id, Closer closer) : id_(id), closer_(closer) {}
  H5Id(H5Id&& other) noexcept
      : id_(std::exchange(other.id_, H5I_INVALID_HID)), closer_(other.closer_) {}
  H5Id(const H5Id&) = delete;
  H5Id& operator=(const H5Id&) = delete;
  H5Id& operator=(H5Id&&) = delete;
  ~H5Id() { close(); }
  hid_t get() const { return id_; }
  // Explicit close for the file, where a failure to flush must be reported.
  herr_t close() {
    herr_t status = id_ >= 0 ? closer_(id_) : 0;
    id_ = H5I_INVALID_HID;
    return status;
  }

 private:
  hid_t id_;
  Closer closer_;
};

// Turns off HDF5's printing of its error stack for the lifetime of this object: a bad file
// must give our one-line exception, not a stack dump on stderr.
class QuietErrors {
 public:
  QuietErrors() {
    // HDF5 1.10 leaks free-list blocks when a checksum fails, and its exit handler then prints
    // "infinite loop closing library" to stderr. We close every file we open, so the exit
    // handler has nothing to do; skip it. Only effective before the library's first use.
    static const bool no_atexit = (H5dont_atexit(), true);
    (void)no_atexit;
    H5Eget_auto2(H5E_DEFAULT, &func_, &data_);
    H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
  }
  QuietErrors(const QuietErrors&) = delete;
  QuietErrors& operator=(const QuietErrors&) = delete;
  ~QuietErrors() { H5Eset_auto2(H5E_DEFAULT, func_, data_); }

 private:
  H5E_auto2_t func_ = nullptr;
  void* data_ = nullptr;
};

// The most specific description on HDF5's current error stack (e.g. "truncated file: ...").
std::string hdf5_reason() {
  std::string reason;
  H5Ewalk2(
      H5E_DEFAULT, H5E_WALK_UPWARD,
      [](unsigned n, const H5E_error2_t* err, void* out) -> herr_t {
        if (n == 0 && err->desc != nullptr) *static_cast<std::string*>(out) = err->desc;
        return 0;
      },
      &reason);
  return reason;
}

[[noreturn]] void fail(const std::string& what) {
  std::string reason = hdf5_reason();
  throw Failure(reason.empty() ? what : what + ": " + reason);
}

hid_t check_id(hid_t id, const std::string& what) {
  if (id < 0) fail(what);
  return id;
}

void check(herr_t status, const std::string& what) {
  if (status < 0) fail(what);
}

H5Id dataspace(const std::vector<hsize_t>& dims) {
  if (dims.empty()) return {check_id(H5Screate(H5S_SCALAR), "cannot create dataspace"), H5Sclose};
  return {check_id(H5Screate_simple(static_cast<int>(dims.size()), dims.data(), nullptr),
                   "cannot create dataspace"),
          H5Sclose};
}

// Object creation properties without modification times, so equal input gives equal bytes.
H5Id untimed_plist(hid_t cls) {
  H5Id plist(check_id(H5Pcreate(cls), "cannot create property list"), H5Pclose);
  check(H5Pset_obj_track_times(plist.get(), 0), "cannot disable time tracking");
  return plist;
}

// ---------------------------------------------------------------- writing

// Fixed-length, null-padded strings: deterministic, and h5py reads them as bytes.
H5Id string_type(size_t length) {
  H5Id type(check_id(H5Tcopy(H5T_C_S1), "cannot create string type"), H5Tclose);
  check(H5Tset_size(type.get(), std::max<size_t>(length, 1)), "cannot size string type");
  check(H5Tset_strpad(type.get(), H5T_STR_NULLPAD), "cannot set string padding");
  check(H5Tset_cset(type.get(), H5T_CSET_UTF8), "cannot set string charset");
  return type;
}

void write_attribute(hid_t obj, const std::string& name, hid_t file_type, hid_t mem_type,
                     const std::vector<hsize_t>& dims, const void* values) {
  H5Id space = dataspace(dims);
  H5Id attr(
      check_id(H5Acreate2(obj, name.c_str(), file_type, space.get(), H5P_DEFAULT, H5P_DEFAULT),
               "cannot create attribute '" + name + "'"),
      H5Aclose);
  check(H5Awrite(attr.get(), mem_type, values), "cannot write attribute '" + name + "'");
}

template <typename T>
void write_scalar_attribute(hid_t obj, const std::string& name, hid_t file_type, hid_t mem_type,
                            T value) {
  write_attribute(obj, name, file_type, mem_type, {}, &value);
}

void write_string_attribute(hid_t obj, const std::string& name, const std::string& value) {
  H5Id type = string_type(value.size());
  std::string padded = value;
  padded.resize(std::max<size_t>(value.size(), 1), '\0');
  write_attribute(obj, name, type.get(), type.get(), {}, padded.data());
}

void write_strings_attribute(hid_t obj, const std::string& name,
                             const std::vector<std::string>& values) {
  size_t width = 1;
  for (const std::string& v : values) width = std::max(width, v.size());
  H5Id type = string_type(width);
  std::string buffer(values.size() * width, '\0');
  for (size_t i = 0; i < values.size(); ++i) values[i].copy(buffer.data() + i * width, width);
  write_attribute(obj, name, type.get(), type.get(), {values.size()}, buffer.data());
}

// One dataset; `chunk` empty means contiguous storage, otherwise chunked with deflate.
void write_dataset(hid_t loc, const std::string& name, hid_t file_type, hid_t mem_type,
                   const std::vector<hsize_t>& dims, const std::vector<hsize_t>& chunk,
                   const void* values) {
  H5Id dcpl = untimed_plist(H5P_DATASET_CREATE);
  if (!chunk.empty()) {
    check(H5Pset_chunk(dcpl.get(), static_cast<int>(chunk.size()), chunk.data()),
          "cannot set chunking of '" + name + "'");
    check(H5Pset_deflate(dcpl.get(), 4), "cannot set compression of '" + name + "'");
  }
  H5Id space = dataspace(dims);
  H5Id dset(check_id(H5Dcreate2(loc, name.c_str(), file_type, space.get(), H5P_DEFAULT, dcpl.get(),
                                H5P_DEFAULT),
                     "cannot create dataset '" + name + "'"),
            H5Dclose);
  bool empty = std::find(dims.begin(), dims.end(), hsize_t{0}) != dims.end();
  if (!empty) {
    check(H5Dwrite(dset.get(), mem_type, H5S_ALL, H5S_ALL, H5P_DEFAULT, values),
          "cannot write dataset '" + name + "'");
  }
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
  if (data.bev_packed.empty()) {
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
  if (H5Zfilter_avail(H5Z_FILTER_DEFLATE) <= 0) throw Failure("HDF5 lacks deflate support");
  // The root group is created from the file creation list, so it needs untimed too.
  H5Id fcpl = untimed_plist(H5P_FILE_CREATE);
  // 1.8 file format: checksummed metadata (corruption is detected on read), and readable by
  // every HDF5 since 1.8. Pinning both bounds keeps the bytes independent of library version.
  H5Id fapl(check_id(H5Pcreate(H5P_FILE_ACCESS), "cannot create property list"), H5Pclose);
  check(H5Pset_libver_bounds(fapl.get(), H5F_LIBVER_V18, H5F_LIBVER_V18), "cannot set file format");
  H5Id file(check_id(H5Fcreate(file_path.c_str(), H5F_ACC_TRUNC, fcpl.get(), fapl.get()),
                     "cannot create " + file_path),
            H5Fclose);
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
  if (data.bev_packed.empty()) {
    write_dataset(root, "bev", H5T_STD_U8LE, H5T_NATIVE_UINT8, {t, c, h, w}, {1, c, h, w},
                  data.bev.data());
  } else {
    write_packed_bev(root, data);
  }
  write_dataset(root, "speed", H5T_IEEE_F32LE, H5T_NATIVE_FLOAT, {t}, {}, data.speed.data());
  write_dataset(root, "action", H5T_IEEE_F32LE, H5T_NATIVE_FLOAT, {t, a}, {}, data.action.data());
  write_dataset(root, "command", H5T_STD_I32LE, H5T_NATIVE_INT32, {t}, {}, data.command.data());
  write_dataset(root, "pose", H5T_IEEE_F32LE, H5T_NATIVE_FLOAT, {t, 3}, {}, data.pose.data());

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

// ---------------------------------------------------------------- reading

H5Id open_attribute(hid_t obj, const std::string& name) {
  const htri_t exists = H5Aexists(obj, name.c_str());
  if (exists < 0) fail("cannot read attribute '" + name + "'");
  if (exists == 0) throw Failure("missing attribute '" + name + "'");
  return {check_id(H5Aopen(obj, name.c_str(), H5P_DEFAULT), "cannot open attribute '" + name + "'"),
          H5Aclose};
}

// Number of elements of a scalar or 1-D attribute.
size_t attribute_length(hid_t attr, const std::string& name, bool want_scalar) {
  H5Id space(check_id(H5Aget_space(attr), "cannot read attribute '" + name + "'"), H5Sclose);
  int rank = H5Sget_simple_extent_ndims(space.get());
  hssize_t count = H5Sget_simple_extent_npoints(space.get());
  if (rank < 0 || count < 0) fail("cannot read attribute '" + name + "'");
  if (want_scalar ? count != 1 : rank > 1) {
    throw Failure("attribute '" + name + "' has the wrong shape");
  }
  return static_cast<size_t>(count);
}

template <typename T>
T read_scalar_attribute(hid_t obj, const std::string& name, hid_t mem_type, H5T_class_t expected) {
  H5Id attr = open_attribute(obj, name);
  H5Id type(check_id(H5Aget_type(attr.get()), "cannot read attribute '" + name + "'"), H5Tclose);
  if (H5Tget_class(type.get()) != expected) {
    throw Failure("attribute '" + name + "' has the wrong type");
  }
  attribute_length(attr.get(), name, true);
  T value{};
  check(H5Aread(attr.get(), mem_type, &value), "cannot read attribute '" + name + "'");
  return value;
}

// Strings as written by us (fixed length) or by others (h5py writes variable length).
std::vector<std::string> read_strings(hid_t obj, const std::string& name, bool want_scalar) {
  H5Id attr = open_attribute(obj, name);
  H5Id type(check_id(H5Aget_type(attr.get()), "cannot read attribute '" + name + "'"), H5Tclose);
  if (H5Tget_class(type.get()) != H5T_STRING) {
    throw Failure("attribute '" + name + "' is not a string");
  }
  const size_t count = attribute_length(attr.get(), name, want_scalar);
  std::vector<std::string> out;
  out.reserve(count);
  const htri_t variable = H5Tis_variable_str(type.get());
  if (variable < 0) fail("cannot read attribute '" + name + "'");
  if (variable > 0) {
    H5Id mem(check_id(H5Tcopy(H5T_C_S1), "cannot create string type"), H5Tclose);
    check(H5Tset_size(mem.get(), H5T_VARIABLE), "cannot size string type");
    check(H5Tset_cset(mem.get(), H5Tget_cset(type.get())), "cannot set string charset");
    std::vector<char*> ptrs(count, nullptr);
    // HDF5 allocates each string; free them even if copying throws.
    struct Release {
      std::vector<char*>& p;
      ~Release() {
        for (char* s : p) H5free_memory(s);
      }
    } release{ptrs};
    if (count > 0) {
      check(H5Aread(attr.get(), mem.get(), ptrs.data()), "cannot read attribute '" + name + "'");
    }
    for (const char* s : ptrs) out.emplace_back(s != nullptr ? s : "");
  } else {
    const size_t width = H5Tget_size(type.get());
    if (width == 0) fail("cannot read attribute '" + name + "'");
    const H5T_str_t pad = H5Tget_strpad(type.get());
    std::string buffer(count * width, '\0');
    if (count > 0) {
      check(H5Aread(attr.get(), type.get(), buffer.data()), "cannot read attribute '" + name + "'");
    }
    for (size_t i = 0; i < count; ++i) {
      std::string s = buffer.substr(i * width, width);
      if (pad == H5T_STR_SPACEPAD) {
        s.erase(s.find_last_not_of(' ') + 1);
      } else {
        s.erase(std::min(s.find('\0'), s.size()));
      }
      out.push_back(std::move(s));
    }
  }
  return out;
}

std::string read_string_attribute(hid_t obj, const std::string& name) {
  return read_strings(obj, name, true).front();
}

// Names of the attributes on `obj`, in name order.
std::vector<std::string> attribute_names(hid_t obj) {
  std::vector<std::string> names;
  hsize_t index = 0;
  herr_t status = H5Aiterate2(
      obj, H5_INDEX_NAME, H5_ITER_INC, &index,
      [](hid_t, const char* name, const H5A_info_t*, void* out) -> herr_t {
        try {
          static_cast<std::vector<std::string>*>(out)->emplace_back(name);
          return 0;
        } catch (...) {  // exceptions must not cross the C library
          return -1;
        }
      },
      &names);
  check(status, "cannot list attributes");
  return names;
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

void require_link(hid_t loc, const std::string& name, const std::string& what) {
  const htri_t exists = H5Lexists(loc, name.c_str(), H5P_DEFAULT);
  if (exists < 0) fail("cannot look up " + what);
  if (exists == 0) throw Failure("missing " + what);
}

template <typename T>
struct Array {
  std::vector<hsize_t> dims;
  std::vector<T> values;
};

template <typename T>
Array<T> read_dataset(hid_t loc, const std::string& name, const std::string& label, hid_t mem_type,
                      H5T_class_t expected, int rank) {
  require_link(loc, name, "dataset '" + label + "'");
  H5Id dset(check_id(H5Dopen2(loc, name.c_str(), H5P_DEFAULT), "cannot open '" + label + "'"),
            H5Dclose);
  H5Id type(check_id(H5Dget_type(dset.get()), "cannot read '" + label + "'"), H5Tclose);
  if (H5Tget_class(type.get()) != expected) {
    throw Failure("dataset '" + label + "' has the wrong type");
  }
  H5Id space(check_id(H5Dget_space(dset.get()), "cannot read '" + label + "'"), H5Sclose);
  if (H5Sget_simple_extent_ndims(space.get()) != rank) {
    throw Failure("dataset '" + label + "' should have rank " + std::to_string(rank));
  }
  Array<T> out;
  out.dims.resize(static_cast<size_t>(rank));
  check(H5Sget_simple_extent_dims(space.get(), out.dims.data(), nullptr),
        "cannot read '" + label + "'");
  size_t count = 1;
  for (hsize_t d : out.dims) {
    if (d != 0 && count > std::numeric_limits<size_t>::max() / sizeof(T) / d) {
      throw Failure("dataset '" + label + "' is impossibly large");
    }
    count *= static_cast<size_t>(d);
  }
  out.values.resize(count);
  if (count > 0) {
    check(H5Dread(dset.get(), mem_type, H5S_ALL, H5S_ALL, H5P_DEFAULT, out.values.data()),
          "cannot read '" + label + "'");
  }
  return out;
}

int dim_as_int(hsize_t d, const std::string& label) {
  if (d > static_cast<hsize_t>(std::numeric_limits<int>::max())) {
    throw Failure("dataset '" + label + "' has a dimension too large");
  }
  return static_cast<int>(d);
}

EpisodeData read_data(hid_t root, const EpisodeMeta& meta) {
  EpisodeData data;
  auto bev = read_dataset<uint8_t>(root, "bev", "bev", H5T_NATIVE_UINT8, H5T_INTEGER, 4);
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
  expect_frames("bev", bev.dims[0]);
  expect_frames("action", action.dims[0]);
  expect_frames("command", command.dims[0]);
  expect_frames("pose", pose.dims[0]);
  if (pose.dims[1] != 3) throw Failure("dataset 'pose' should have 3 columns");

  const hsize_t stored_frames = static_cast<hsize_t>(
      read_scalar_attribute<int64_t>(root, "frames", H5T_NATIVE_INT64, H5T_INTEGER));
  if (stored_frames != frames) {
    throw Failure("attribute 'frames' is " + std::to_string(stored_frames) + " but datasets have " +
                  std::to_string(frames));
  }
  if (meta.channels.size() != bev.dims[1]) {
    throw Failure("attribute 'channels' names " + std::to_string(meta.channels.size()) +
                  " channels, bev has " + std::to_string(bev.dims[1]));
  }
  if (meta.action_names.size() != action.dims[1]) {
    throw Failure("attribute 'action_names' names " + std::to_string(meta.action_names.size()) +
                  " actions, action has " + std::to_string(action.dims[1]));
  }

  data.channels = dim_as_int(bev.dims[1], "bev");
  data.height = dim_as_int(bev.dims[2], "bev");
  data.width = dim_as_int(bev.dims[3], "bev");
  data.action_dim = dim_as_int(action.dims[1], "action");
  data.bev.assign(bev.values.begin(), bev.values.end());
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

// Opens an existing episode read-only. A missing or unreadable file is an IoError; anything
// HDF5 cannot make sense of is reported by the caller as a DataError.
H5Id open_for_reading(const std::string& path) {
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) throw IoError("episode file " + path + " not found");
  if (::access(path.c_str(), R_OK) != 0) {
    throw IoError("episode file " + path + " is not readable: " + std::strerror(errno));
  }
  htri_t is_hdf5 = H5Fis_hdf5(path.c_str());
  if (is_hdf5 == 0) throw Failure("not an HDF5 file");
  if (is_hdf5 < 0) fail("cannot open");
  return {check_id(H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), "cannot open"), H5Fclose};
}

// Runs a read, turning every failure that is not already one of ours into a DataError.
template <typename F>
auto guarded_read(const std::string& path, F&& read) {
  QuietErrors quiet;
  try {
    return read();
  } catch (const Error&) {
    throw;
  } catch (const std::bad_alloc&) {
    throw DataError("malformed episode file " + path + ": data too large to load");
  } catch (const std::exception& e) {
    throw DataError("malformed episode file " + path + ": " + e.what());
  }
}

}  // namespace

void write_episode(const std::string& path, const EpisodeMeta& meta, const EpisodeData& data) {
  validate(meta, data);
  QuietErrors quiet;
  const std::string tmp = temp_path_for(path);
  try {
    write_file(tmp, meta, data);
    commit_temp_file(tmp, path);
  } catch (const std::exception& e) {
    std::error_code ec;
    std::filesystem::remove(tmp, ec);
    throw IoError("cannot write episode " + path + ": " + e.what());
  }
}

EpisodeData read_episode(const std::string& path, EpisodeMeta* meta) {
  return guarded_read(path, [&] {
    H5Id file = open_for_reading(path);
    EpisodeMeta m = read_meta(file.get());
    EpisodeData data = read_data(file.get(), m);
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
