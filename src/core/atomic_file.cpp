#include "core/atomic_file.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>

#include "core/error.hpp"
#include "core/mpi.hpp"
#include "core/process.hpp"

namespace cd {

std::string temp_path_for(const std::string& final_path) {
  // Host, MPI rank and pid keep concurrent writers apart (worker processes; ranks on other
  // nodes, whose containers may reuse a pid); ".tmp" marks it as unfinished.
  std::string host = host_name();
  for (char& c : host)
    if (c == '/' || c == ' ') c = '_';
  return final_path + "." + host + "." + std::to_string(mpi_place().rank) + "." +
         std::to_string(::getpid()) + ".tmp";
}

void commit_temp_file(const std::string& tmp, const std::string& final_path) {
  int fd = ::open(tmp.c_str(), O_RDONLY);
  if (fd < 0) throw IoError("cannot open " + tmp + ": " + std::strerror(errno));
  ::fsync(fd);
  ::close(fd);
  if (std::rename(tmp.c_str(), final_path.c_str()) != 0) {
    std::string why = std::strerror(errno);
    std::remove(tmp.c_str());
    throw IoError("cannot rename " + tmp + " to " + final_path + ": " + why);
  }
}

void write_file_atomic(const std::string& path, const std::string& content) {
  std::filesystem::path p(path);
  if (p.has_parent_path()) std::filesystem::create_directories(p.parent_path());
  std::string tmp = temp_path_for(path);
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out) throw IoError("cannot write " + tmp);
    out.write(content.data(), static_cast<std::streamsize>(content.size()));
    if (!out) throw IoError("write failed for " + tmp);
  }
  commit_temp_file(tmp, path);
}

std::string read_file_bytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw IoError("cannot read " + path);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

void remove_stale_temporaries(const std::string& dir) {
  // Under MPI, rank 0 cleans and no rank writes into the folder before it is done.
  if (mpi_lead()) {
    std::error_code ec;
    for (const auto& e : std::filesystem::directory_iterator(dir, ec))
      if (e.path().filename().string().ends_with(".tmp")) std::filesystem::remove(e.path(), ec);
  }
  mpi_barrier();
}

}  // namespace cd
