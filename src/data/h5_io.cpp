#include "data/h5_io.hpp"

#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>

#include "core/atomic_file.hpp"

namespace cd::h5 {

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

bool has_link(hid_t loc, const std::string& name, const std::string& what) {
  const htri_t exists = H5Lexists(loc, name.c_str(), H5P_DEFAULT);
  if (exists < 0) fail("cannot look up " + what);
  return exists > 0;
}

void require_link(hid_t loc, const std::string& name, const std::string& what) {
  if (!has_link(loc, name, what)) throw Failure("missing " + what);
}

int dim_as_int(hsize_t d, const std::string& label) {
  if (d > static_cast<hsize_t>(std::numeric_limits<int>::max())) {
    throw Failure("dataset '" + label + "' has a dimension too large");
  }
  return static_cast<int>(d);
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

H5Id create_file(const std::string& path) {
  if (H5Zfilter_avail(H5Z_FILTER_DEFLATE) <= 0) throw Failure("HDF5 lacks deflate support");
  // The root group is created from the file creation list, so it needs untimed too.
  H5Id fcpl = untimed_plist(H5P_FILE_CREATE);
  // 1.8 file format: checksummed metadata (corruption is detected on read), and readable by
  // every HDF5 since 1.8. Pinning both bounds keeps the bytes independent of library version.
  H5Id fapl(check_id(H5Pcreate(H5P_FILE_ACCESS), "cannot create property list"), H5Pclose);
  check(H5Pset_libver_bounds(fapl.get(), H5F_LIBVER_V18, H5F_LIBVER_V18), "cannot set file format");
  return {check_id(H5Fcreate(path.c_str(), H5F_ACC_TRUNC, fcpl.get(), fapl.get()),
                   "cannot create " + path),
          H5Fclose};
}

void write_atomically(const std::string& path, const std::function<void(const std::string&)>& write) {
  QuietErrors quiet;
  const std::string tmp = temp_path_for(path);
  try {
    write(tmp);
    commit_temp_file(tmp, path);
  } catch (const std::exception& e) {
    std::error_code ec;
    std::filesystem::remove(tmp, ec);
    throw IoError("cannot write episode " + path + ": " + e.what());
  }
}

bool episode_complete(const std::string& path,
                      const std::function<void(const std::string&)>& read_meta) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) return false;
  try {
    read_meta(path);
    return true;
  } catch (const Error&) {
    return false;
  }
}

}  // namespace cd::h5
