#pragma once
// One job at a time in a run folder. A job that writes a folder (collect, train, eval, suite
// --builtin) holds `DIR/causaldrive.lock`: a file beside the folder's record naming the
// holder (host, pid, command, start time), locked with flock(2). A second job into the same
// folder is refused at once with one line naming the holder. flock dies with its process, so
// a lock file left by a dead job is free: the next job takes it over and says so.
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

  struct Impl;  // run_lock.cpp
  explicit RunLock(std::shared_ptr<Impl> impl) : impl_(std::move(impl)) {}

 private:
  std::shared_ptr<Impl> impl_;
};

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
