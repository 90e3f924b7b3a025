#pragma once
// One job at a time in a run folder. A job that writes a folder (collect, train, eval, suite
// --builtin) holds `DIR/causaldrive.lock`: a file naming the holder (command, host, pid, start
// time, a random token) with a heartbeat counter the holder rewrites every period, locked with
// flock(2) where the file system has it. A second job into the same folder is refused with one
// line naming the holder. A holder that died is taken over, with one line saying so: at once
// when flock proves it (or its pid is gone from this host), after three silent heartbeat
// periods for a holder on another host (node-local flock, or no flock at all: docs/cluster.md).
// The file is never removed while held; a released one says "state released".
//
// Within one process the lock is re-entrant (dagger's rounds, cim's validation eval write into
// folders their caller may hold); forked workers inherit their parent's hold. The ranks of an
// MPI job share their job's lock: rank 0 takes it, the others only mark it held (core/mpi).
#include <memory>
#include <string>

#include "core/error.hpp"

namespace cd {

// The folder is held by another live job.
struct BusyError : Error {
  using Error::Error;
};

class RunLock {
 public:
  RunLock() = default;
  RunLock(RunLock&&) noexcept;
  RunLock& operator=(RunLock&&) noexcept;
  RunLock(const RunLock&) = delete;
  RunLock& operator=(const RunLock&) = delete;
  ~RunLock();

  bool held() const { return impl_ != nullptr; }
  void release();
  // Throws BusyError when another job took the folder over while this one held it (its
  // heartbeat saw another holder's token: docs/cluster.md). A job checks before its summary.
  void check() const;

  struct Impl;  // run_lock.cpp
  explicit RunLock(std::shared_ptr<Impl> impl) : impl_(std::move(impl)) {}

 private:
  std::shared_ptr<Impl> impl_;
};

// The heartbeat period in seconds: CAUSALDRIVE_LOCK_BEAT_S, default 10 (a ConfigError when it
// is not a number in (0, 3600]). A holder on another host that has not beaten for three periods
// is taken over.
inline constexpr const char* kLockBeatEnv = "CAUSALDRIVE_LOCK_BEAT_S";
double lock_beat_seconds();

// For the tests of file systems without flock, or with a node-local one: the flock(2) the lock
// calls (nullptr: the real one).
namespace lock_testing {
using FlockFn = int (*)(int fd, int operation);
void set_flock(FlockFn fn);
}  // namespace lock_testing

// The lock file's name inside a run folder.
inline constexpr const char* kRunLockName = "causaldrive.lock";

// Creates `dir` when missing and takes its lock for `command` ("eval", "train", ...). Throws
// BusyError ("DIR is held by eval (host H, pid P, since T); ...") when a live job holds it,
// IoError when the folder or lock file cannot be made. A lock file whose holder died is taken
// over with one line on stderr naming the dead holder. Held until the RunLock is released or
// destroyed; nested calls for a folder this process holds return a no-op RunLock.
RunLock lock_run_folder(const std::string& dir, const std::string& command);

// Marks `dir` as held by this process without taking the file lock: an MPI rank other than 0,
// whose job's rank 0 holds it.
RunLock share_run_folder(const std::string& dir);

// The holder's line of a lock file ("eval (host H, pid P, since T)"), or "" when it is empty.
std::string describe_lock_holder(const std::string& lock_file_content);

}  // namespace cd
