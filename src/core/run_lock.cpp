#include "core/run_lock.hpp"

#include "core/mpi.hpp"
#include "core/process.hpp"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <map>
#include <mutex>
#include <sstream>

namespace cd {

namespace fs = std::filesystem;

struct RunLock::Impl {
  std::string key;   // the folder's canonical path
  std::string file;  // its lock file
  int fd = -1;       // -1: shared (an MPI rank that is not rank 0)
  pid_t owner = 0;
  bool created = false;  // the lock made the folder: an empty one is removed on release
  ~Impl();
};

namespace {

std::mutex registry_mutex;
std::map<std::string, std::weak_ptr<RunLock::Impl>>& registry() {
  static std::map<std::string, std::weak_ptr<RunLock::Impl>> r;
  return r;
}

std::string utc_now() {
  std::time_t t = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&t, &tm);
  char buf[32];
  std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", &tm);
  return buf;
}

std::string read_fd(int fd) {
  std::string out;
  char buf[512];
  if (lseek(fd, 0, SEEK_SET) < 0) return out;
  for (ssize_t n; (n = read(fd, buf, sizeof buf)) > 0;) out.append(buf, static_cast<size_t>(n));
  return out;
}

// The folder, created, as one canonical key; *created says whether it was made here.
std::string folder_key(const std::string& dir, bool* created) {
  std::error_code ec;
  *created = !fs::exists(dir, ec);
  fs::create_directories(dir, ec);
  if (ec) throw IoError("cannot create output folder " + dir + ": " + ec.message());
  fs::path p = fs::canonical(dir, ec);
  if (ec) throw IoError("cannot resolve output folder " + dir + ": " + ec.message());
  return p.string();
}

// An existing hold of `key` by this process, or null.
std::shared_ptr<RunLock::Impl> held_here(const std::string& key) {
  auto it = registry().find(key);
  if (it == registry().end()) return nullptr;
  return it->second.lock();  // a forked worker's inherited hold counts: its parent holds it
}

}  // namespace

RunLock::Impl::~Impl() {
  if (owner != getpid()) return;  // a forked worker never releases its parent's lock
  {
    std::lock_guard<std::mutex> g(registry_mutex);
    auto it = registry().find(key);
    if (it != registry().end() && it->second.expired()) registry().erase(it);
  }
  if (fd >= 0) {
    // Unlink first, then unlock: a job that opened the old file sees it is gone and retries.
    ::unlink(file.c_str());
    ::close(fd);
  }
  if (created) ::rmdir(key.c_str());  // only when empty: a job that failed early leaves nothing
}

RunLock::RunLock(RunLock&&) noexcept = default;
RunLock& RunLock::operator=(RunLock&&) noexcept = default;
RunLock::~RunLock() = default;
void RunLock::release() { impl_.reset(); }

std::string describe_lock_holder(const std::string& content) {
  std::map<std::string, std::string> kv;
  std::istringstream in(content);
  for (std::string line; std::getline(in, line);) {
    auto sp = line.find(' ');
    if (sp != std::string::npos) kv[line.substr(0, sp)] = line.substr(sp + 1);
  }
  if (kv.empty()) return "";
  auto get = [&](const char* k) { return kv.count(k) ? kv[k] : std::string("?"); };
  return get("command") + " (host " + get("host") + ", pid " + get("pid") + ", since " +
         get("started") + ")";
}

namespace {

RunLock lock_here(const std::string& dir, const std::string& command) {
  bool created = false;
  const std::string key = folder_key(dir, &created);
  std::lock_guard<std::mutex> g(registry_mutex);
  if (auto impl = held_here(key)) return RunLock(impl);
  const std::string file = (fs::path(key) / kRunLockName).string();
  for (int attempt = 0; attempt < 16; ++attempt) {
    int fd = ::open(file.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
    if (fd < 0)
      throw IoError("cannot open the lock file " + file + ": " + std::strerror(errno));
    if (::flock(fd, LOCK_EX | LOCK_NB) != 0) {
      const int err = errno;
      std::string holder = describe_lock_holder(read_fd(fd));
      ::close(fd);
      if (err != EWOULDBLOCK)
        throw IoError("cannot lock " + file + ": " + std::strerror(err));
      throw BusyError(dir + " is held by " + (holder.empty() ? "another job" : holder) +
                      "; wait for it to finish or use another folder");
    }
    // The file may have been released (unlinked) between our open and our lock: retry.
    struct stat by_fd{}, by_path{};
    if (::fstat(fd, &by_fd) != 0 || ::stat(file.c_str(), &by_path) != 0 ||
        by_fd.st_ino != by_path.st_ino || by_fd.st_dev != by_path.st_dev) {
      ::close(fd);
      continue;
    }
    const std::string previous = describe_lock_holder(read_fd(fd));
    if (!previous.empty())
      std::fprintf(stderr, "causaldrive: %s: taking over the lock of %s, which has ended\n",
                   dir.c_str(), previous.c_str());
    std::ostringstream me;
    me << "command " << command << "\nhost " << host_name() << "\npid " << getpid()
       << "\nstarted " << utc_now() << "\n";
    const std::string text = me.str();
    if (::ftruncate(fd, 0) != 0 || ::pwrite(fd, text.data(), text.size(), 0) !=
                                       static_cast<ssize_t>(text.size())) {
      ::close(fd);
      throw IoError("cannot write the lock file " + file + ": " + std::strerror(errno));
    }
    auto impl = std::make_shared<RunLock::Impl>();
    impl->key = key;
    impl->file = file;
    impl->fd = fd;
    impl->owner = getpid();
    impl->created = created;
    registry()[key] = impl;
    return RunLock(impl);
  }
  throw IoError("cannot take the lock " + file + ": it keeps being replaced");
}

}  // namespace

RunLock lock_run_folder(const std::string& dir, const std::string& command) {
  if (!mpi_distributed()) return lock_here(dir, command);
  // One MPI job, one lock: rank 0 takes it and tells the others whether it could.
  RunLock lock;
  std::string error;
  if (mpi_lead()) {
    try {
      lock = lock_here(dir, command);
    } catch (const Error& e) {
      error = e.what();
      mpi_broadcast(error);  // the other ranks stop too
      throw;
    }
  }
  error = mpi_broadcast(error);
  if (!error.empty()) throw MpiEchoError(error);
  return mpi_lead() ? std::move(lock) : share_run_folder(dir);
}

RunLock share_run_folder(const std::string& dir) {
  bool created = false;
  const std::string key = folder_key(dir, &created);
  std::lock_guard<std::mutex> g(registry_mutex);
  if (auto impl = held_here(key)) return RunLock(impl);
  auto impl = std::make_shared<RunLock::Impl>();
  impl->key = key;
  impl->file = (fs::path(key) / kRunLockName).string();
  impl->owner = getpid();
  registry()[key] = impl;
  return RunLock(impl);
}

}  // namespace cd
