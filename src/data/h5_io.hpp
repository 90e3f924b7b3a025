#pragma once
// The HDF5 building blocks every episode file of the project is made of (driving episodes,
// MuJoCo-Image episodes): owned identifiers, quiet error stacks, deterministic attributes and
// datasets (no timestamps, 1.8 file format), validated reads, atomic file creation.
// Helpers throw h5::Failure with what went wrong; the public reader/writer functions add the path
// and turn it into IoError or DataError.
#include <hdf5.h>

#include <algorithm>
#include <functional>
#include <limits>
#include <new>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "core/error.hpp"

namespace cd::h5 {

// Raised by the helpers below; the public functions turn it into IoError or DataError with the
// file's path, so each helper only has to say what went wrong.
struct Failure : std::runtime_error {
  using std::runtime_error::runtime_error;
};

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
std::string hdf5_reason();

[[noreturn]] void fail(const std::string& what);

hid_t check_id(hid_t id, const std::string& what);

void check(herr_t status, const std::string& what);

H5Id dataspace(const std::vector<hsize_t>& dims);

// Object creation properties without modification times, so equal input gives equal bytes.
H5Id untimed_plist(hid_t cls);

// Fixed-length, null-padded strings: deterministic, and h5py reads them as bytes.
H5Id string_type(size_t length);

void write_attribute(hid_t obj, const std::string& name, hid_t file_type, hid_t mem_type,
                     const std::vector<hsize_t>& dims, const void* values);

void write_string_attribute(hid_t obj, const std::string& name, const std::string& value);

void write_strings_attribute(hid_t obj, const std::string& name,
                             const std::vector<std::string>& values);

// One dataset; `chunk` empty means contiguous storage, otherwise chunked with deflate.
void write_dataset(hid_t loc, const std::string& name, hid_t file_type, hid_t mem_type,
                   const std::vector<hsize_t>& dims, const std::vector<hsize_t>& chunk,
                   const void* values);

H5Id open_attribute(hid_t obj, const std::string& name);

// Number of elements of a scalar or 1-D attribute.
size_t attribute_length(hid_t attr, const std::string& name, bool want_scalar);

// Strings as written by us (fixed length) or by others (h5py writes variable length).
std::vector<std::string> read_strings(hid_t obj, const std::string& name, bool want_scalar);

std::string read_string_attribute(hid_t obj, const std::string& name);

// Names of the attributes on `obj`, in name order.
std::vector<std::string> attribute_names(hid_t obj);

void require_link(hid_t loc, const std::string& name, const std::string& what);
bool has_link(hid_t loc, const std::string& name, const std::string& what);

int dim_as_int(hsize_t d, const std::string& label);

// Opens an existing episode read-only. A missing or unreadable file is an IoError; anything
// HDF5 cannot make sense of is reported by the caller as a DataError.
H5Id open_for_reading(const std::string& path);

// Creates `path` (truncating) with untimed objects and the 1.8 file format pinned.
H5Id create_file(const std::string& path);

// Writes a file atomically: write(tmp) fills a temporary file beside `path`, which is then
// fsynced and renamed. Any failure removes the temporary and throws IoError naming `path`.
void write_atomically(const std::string& path, const std::function<void(const std::string&)>& write);

// Whether `path` is a finished episode file: it exists and read_meta(path) reads it without an
// Error (a damaged or half-written file is recorded again by a resumed collection).
bool episode_complete(const std::string& path,
                      const std::function<void(const std::string&)>& read_meta);

template <typename T>
void write_scalar_attribute(hid_t obj, const std::string& name, hid_t file_type, hid_t mem_type,
                            T value) {
  write_attribute(obj, name, file_type, mem_type, {}, &value);
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

template <typename T>
struct Array {
  std::vector<hsize_t> dims;
  std::vector<T> values;
};

// The dataset's dims and (with read_values) its values, checked for type class and rank.
template <typename T>
Array<T> read_dataset(hid_t loc, const std::string& name, const std::string& label, hid_t mem_type,
                      H5T_class_t expected, int rank, bool read_values = true) {
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
  if (!read_values) return out;
  out.values.resize(count);
  if (count > 0) {
    check(H5Dread(dset.get(), mem_type, H5S_ALL, H5S_ALL, H5P_DEFAULT, out.values.data()),
          "cannot read '" + label + "'");
  }
  return out;
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

}  // namespace cd::h5
