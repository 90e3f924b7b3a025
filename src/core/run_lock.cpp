#include "core/run_lock.hpp"

#include "core/mpi.hpp"
#include "core/process.hpp"

#include <fcntl.h>
#include <signal.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <map>
#include <mutex>
#include <random>
#include <sstream>
#include <thread>

namespace cd {

namespace fs = std::filesystem;

namespace lock_testing {
namespace {
FlockFn flock_fn = ::flock;
}
void set_flock(FlockFn fn) { flock_fn = fn ? fn : ::flock; }
}  // namespace lock_testing

struct RunLock::Impl {
  std::string dir;   // as the caller named it (messages)
  std::string key;   // the folder's canonical path
  std::string file;  // its lock file
  int fd = -1;       // -1: shared (an MPI rank that is not rank 0)
  pid_t owner = 0;
  bool created = false;  // the lock made the folder: an empty one is removed on release
  std::string head;      // the holder's lines (command, host, pid, started, token)
  std::string token;
  long beat = 0;
  // The heartbeat: a thread that rewrites `beat` every beat period, and notices when the file
  // names another holder (a job on another node judged this one stale).
  std::unique_ptr<std::thread> heart;
  std::mutex mutex;
  std::condition_variable wake;
  bool stopping = false;
  std::atomic<bool> lost{false};
  std::string lost_to;  // under `mutex`
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

using Clock = std::chrono::steady_clock;
using Seconds = std::chrono::duration<double>;

// The file's content through a new open: on NFS, close-to-open consistency makes another
// node's last write visible to a new open, not to a descriptor held open. "" when unreadable.
std::string read_path(const std::string& path) {
  int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) return "";
  std::string out;
  char buf[512];
  for (ssize_t n; (n = ::read(fd, buf, sizeof buf)) > 0;) out.append(buf, static_cast<size_t>(n));
  ::close(fd);
  return out;
}

std::map<std::string, std::string> parse_lock(const std::string& content) {
  std::map<std::string, std::string> kv;
  std::istringstream in(content);
  for (std::string line; std::getline(in, line);) {
    auto sp = line.find(' ');
    if (sp != std::string::npos) kv[line.substr(0, sp)] = line.substr(sp + 1);
  }
  return kv;
}

// Writes the file's new content over the old, then cuts it to length: a reader never sees it
// empty (a heartbeat's rewrite read as "no holder" would let a job without flock take a live
// lock), at worst the new head over the old tail for a moment when the text shrinks.
bool write_fd(int fd, const std::string& text) {
  return ::pwrite(fd, text.data(), text.size(), 0) == static_cast<ssize_t>(text.size()) &&
         ::ftruncate(fd, static_cast<off_t>(text.size())) == 0 && ::fdatasync(fd) == 0;
}

// flock(2) errors that mean "no flock on this file system" (Lustre without -o flock: ENOSYS;
// some NFS setups: ENOLCK), not "held".
bool flock_unsupported(int err) {
  return err == ENOSYS || err == ENOLCK || err == EOPNOTSUPP || err == EINVAL;
}

// Whether a process of this host runs with that pid. A zombie (killed, not yet reaped: a
// container whose init does not reap) has ended: its descriptors, and locks, are gone.
bool pid_alive(const std::string& pid_text) {
  const long pid = std::atol(pid_text.c_str());
  if (pid <= 0) return false;
  if (::kill(static_cast<pid_t>(pid), 0) != 0 && errno != EPERM) return false;
  const std::string stat = read_path("/proc/" + std::to_string(pid) + "/stat");
  const size_t paren = stat.rfind(')');
  return paren == std::string::npos || paren + 2 >= stat.size() || stat[paren + 2] != 'Z';
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

std::string new_token() {
  std::random_device rd;
  char buf[24];
  std::snprintf(buf, sizeof buf, "%08x%08x", rd(), rd());
  return host_name() + ":" + std::to_string(::getpid()) + ":" + buf;
}

void heartbeat(RunLock::Impl* impl, double period) {
  const auto every = std::chrono::duration_cast<Clock::duration>(Seconds(period));
  std::unique_lock<std::mutex> g(impl->mutex);
  while (!impl->wake.wait_for(g, every, [&] { return impl->stopping; })) {
    const std::string now = read_path(impl->file);
    const auto kv = parse_lock(now);
    if (!now.empty() && (kv.count("token") == 0 || kv.at("token") != impl->token)) {
      // Another job took the folder while this one held it: say so once, stop beating (its
      // claim must not be overwritten), and let the job's end refuse to commit (check()).
      impl->lost_to = describe_lock_holder(now);
      impl->lost = true;
      std::fprintf(stderr,
                   "causaldrive: %s: the lock was taken over by %s while this job held it "
                   "(docs/cluster.md); this job will not write its summary\n",
                   impl->dir.c_str(), impl->lost_to.c_str());
      return;
    }
    ++impl->beat;
    write_fd(impl->fd, impl->head + "beat " + std::to_string(impl->beat) + "\nstate held\n");
  }
}

}  // namespace

double lock_beat_seconds() {
  const char* v = std::getenv(kLockBeatEnv);
  if (v == nullptr || *v == '\0') return 10.0;
  char* end = nullptr;
  const double s = std::strtod(v, &end);
  if (end == v || *end != '\0' || !(s > 0) || s > 3600)
    throw ConfigError(std::string(kLockBeatEnv) + " must be a number of seconds in (0, 3600] (got '" +
                      v + "')");
  return s;
}

RunLock::Impl::~Impl() {
  if (owner != getpid()) {
    // A forked worker's copy: the thread exists only in its parent.
    if (heart) (void)heart.release();
    return;
  }
  {
    std::lock_guard<std::mutex> g(registry_mutex);
    auto it = registry().find(key);
    if (it != registry().end() && it->second.expired()) registry().erase(it);
  }
  if (heart) {
    {
      std::lock_guard<std::mutex> g(mutex);
      stopping = true;
    }
    wake.notify_all();
    heart->join();
  }
  if (fd >= 0) {
    // The file stays: a job that opened it meanwhile reads "released" and may take it. (An
    // unlinked file lets a job lock the old inode while another creates a new one.) A taken
    // lock is the new holder's: left as it is.
    if (!lost) write_fd(fd, head + "beat " + std::to_string(beat) + "\nstate released\n");
    // Only a folder this job made and left empty but for the lock goes, with its lock file.
    std::error_code ec;
    if (created && !lost) {
      bool only_lock = true;
      for (const auto& e : fs::directory_iterator(key, ec))
        if (e.path().filename() != kRunLockName) only_lock = false;
      if (!ec && only_lock) ::unlink(file.c_str());
    }
    ::close(fd);
  }
  if (created) ::rmdir(key.c_str());  // only when empty: a job that failed early leaves nothing
}

RunLock::RunLock(RunLock&&) noexcept = default;
RunLock& RunLock::operator=(RunLock&&) noexcept = default;
RunLock::~RunLock() = default;
void RunLock::release() { impl_.reset(); }

void RunLock::check() const {
  if (!impl_ || !impl_->lost) return;
  std::lock_guard<std::mutex> g(impl_->mutex);
  throw BusyError(impl_->dir + " was taken over by " + impl_->lost_to +
                  " while this job held it; its summary was not written (rerun when the other "
                  "job has finished, or use another folder)");
}

std::string describe_lock_holder(const std::string& content) {
  std::map<std::string, std::string> kv = parse_lock(content);
  if (kv.empty()) return "";
  auto get = [&](const char* k) { return kv.count(k) ? kv[k] : std::string("?"); };
  return get("command") + " (host " + get("host") + ", pid " + get("pid") + ", since " +
         get("started") + ")";
}

namespace {

enum class Holder { None, Dead, Live };

// Whether the job the lock file names still holds it. flock (when the file system has it) has
// already kept out a live holder that shares our lock manager; what is left: a holder on
// another node (node-local flock, or none at all), judged by its heartbeat.
Holder judge_holder(const std::string& file, const std::string& dir, bool flocked,
                    std::string* content) {
  auto kv = parse_lock(*content);
  if (kv.empty() || kv["state"] == "released") return Holder::None;
  if (!kv.count("state") || !kv.count("beat")) return Holder::Dead;  // before heartbeats: flock's
  // On this host flock is the kernel's own: had the holder lived, it would have kept us out.
  const bool here = kv["host"] == host_name();
  if (here && (flocked || !pid_alive(kv["pid"]))) return Holder::Dead;
  // Watch the heartbeat for three periods: a live holder beats at least twice.
  const double period = lock_beat_seconds();
  const auto until = Clock::now() + std::chrono::duration_cast<Clock::duration>(Seconds(3 * period));
  std::fprintf(stderr, "causaldrive: %s: %s; waiting up to %g s for its heartbeat\n",
               dir.c_str(),
               ("the lock names " + describe_lock_holder(*content) +
                (here ? "" : " on another host"))
                   .c_str(),
               3 * period);
  while (Clock::now() < until) {
    std::this_thread::sleep_for(Seconds(period / 4));
    const std::string now = read_path(file);
    if (now == *content) continue;
    *content = now;
    auto again = parse_lock(now);
    if (again.empty() || again["state"] == "released") return Holder::None;
    return Holder::Live;  // it beat (or another job claimed it meanwhile)
  }
  return Holder::Dead;
}

RunLock lock_here(const std::string& dir, const std::string& command) {
  bool created = false;
  const std::string key = folder_key(dir, &created);
  std::lock_guard<std::mutex> g(registry_mutex);
  if (auto impl = held_here(key)) return RunLock(impl);
  const std::string file = (fs::path(key) / kRunLockName).string();
  const double period = lock_beat_seconds();
  auto busy = [&](const std::string& content) {
    const std::string holder = describe_lock_holder(content);
    return BusyError(dir + " is held by " + (holder.empty() ? "another job" : holder) +
                     "; wait for it to finish or use another folder");
  };
  for (int attempt = 0; attempt < 16; ++attempt) {
    int fd = ::open(file.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
    if (fd < 0)
      throw IoError("cannot open the lock file " + file + ": " + std::strerror(errno));
    bool flocked = true;
    if (lock_testing::flock_fn(fd, LOCK_EX | LOCK_NB) != 0) {
      const int err = errno;
      if (err == EWOULDBLOCK) {
        const std::string content = read_path(file);
        ::close(fd);
        throw busy(content);
      }
      if (!flock_unsupported(err)) {
        ::close(fd);
        throw IoError("cannot lock " + file + ": " + std::strerror(err));
      }
      flocked = false;  // the heartbeat alone keeps other jobs out
    }
    // A file replaced between our open and our lock (an empty folder's lock removed): retry.
    struct stat by_fd{}, by_path{};
    if (::fstat(fd, &by_fd) != 0 || ::stat(file.c_str(), &by_path) != 0 ||
        by_fd.st_ino != by_path.st_ino || by_fd.st_dev != by_path.st_dev) {
      ::close(fd);
      continue;
    }
    std::string previous = read_path(file);
    const Holder holder = judge_holder(file, dir, flocked, &previous);
    if (holder == Holder::Live) {
      ::close(fd);
      throw busy(previous);
    }
    if (holder == Holder::Dead)
      std::fprintf(stderr, "causaldrive: %s: taking over the lock of %s, which has ended\n",
                   dir.c_str(), describe_lock_holder(previous).c_str());
    auto impl = std::make_shared<RunLock::Impl>();
    impl->dir = dir;
    impl->key = key;
    impl->file = file;
    impl->fd = fd;
    impl->owner = getpid();
    impl->created = created;
    impl->token = new_token();
    std::ostringstream me;
    me << "command " << command << "\nhost " << host_name() << "\npid " << getpid()
       << "\nstarted " << utc_now() << "\ntoken " << impl->token << "\n";
    impl->head = me.str();
    // (On a failure below, the impl is dropped as a stranger's: its release would take the
    // registry mutex held here, and it holds nothing to release.)
    if (!write_fd(fd, impl->head + "beat 0\nstate held\n")) {
      const std::string why = std::strerror(errno);
      impl->owner = 0;
      ::close(fd);
      throw IoError("cannot write the lock file " + file + ": " + why);
    }
    if (!flocked) {
      // Without flock two jobs may claim at once: the last writer wins, the other backs off.
      std::this_thread::sleep_for(Seconds(period / 4));
      const std::string now = read_path(file);
      if (parse_lock(now)["token"] != impl->token) {
        impl->owner = 0;
        ::close(fd);
        throw busy(now);
      }
    }
    impl->heart = std::make_unique<std::thread>(heartbeat, impl.get(), period);
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
  mpi_lead_step([&] { lock = lock_here(dir, command); });
  return mpi_lead() ? std::move(lock) : share_run_folder(dir);
}

RunLock share_run_folder(const std::string& dir) {
  bool created = false;
  const std::string key = folder_key(dir, &created);
  std::lock_guard<std::mutex> g(registry_mutex);
  if (auto impl = held_here(key)) return RunLock(impl);
  auto impl = std::make_shared<RunLock::Impl>();
  impl->dir = dir;
  impl->key = key;
  impl->file = (fs::path(key) / kRunLockName).string();
  impl->owner = getpid();
  registry()[key] = impl;
  return RunLock(impl);
}

}  // namespace cd
