// The run folder's lock (core/run_lock): another holder refuses us with its line, a dead
// holder's file is taken over and said, one process may nest, release marks the file released
// (tests/core/test_run_lock_hosts.cpp: file systems without flock or with a node-local one).
// Another job is simulated by a second open file description of the lock file with its own
// flock, which conflicts with ours even inside this process.
#include "core/run_lock.hpp"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>

#include <filesystem>
#include <string>

#include <gtest/gtest.h>

#include "../support/test_support.hpp"
#include "core/process.hpp"

namespace cd {
namespace {

using test::TempDir;
namespace fs = std::filesystem;

const std::string kOther =
    "command eval\nhost node7\npid 4242\nstarted 2026-11-26T06:00:00Z\n";

// A lock file held by "another job": its fd, flocked; -1 on failure.
int hold_as_other(const std::string& dir) {
  fs::create_directories(dir);
  int fd = ::open((dir + "/" + kRunLockName).c_str(), O_RDWR | O_CREAT, 0644);
  if (fd < 0) return -1;
  if (::flock(fd, LOCK_EX | LOCK_NB) != 0 || ::ftruncate(fd, 0) != 0 ||
      ::write(fd, kOther.data(), kOther.size()) != static_cast<ssize_t>(kOther.size())) {
    ::close(fd);
    return -1;
  }
  return fd;
}

TEST(RunLock, DescribesTheHolderInOneLine) {
  EXPECT_EQ(describe_lock_holder(kOther), "eval (host node7, pid 4242, since 2026-11-26T06:00:00Z)");
  EXPECT_EQ(describe_lock_holder(""), "");
  EXPECT_EQ(describe_lock_holder("command train\npid 7\n"), "train (host ?, pid 7, since ?)");
}

TEST(RunLock, AFolderAnotherJobHoldsIsRefusedNamingTheHolderAndLeftAsItWas) {
  TempDir dir("cdtest-lock");
  const std::string run = dir / "run";
  fs::create_directories(run);
  test::write_text(run + "/results.json", "{\"kept\": 1}\n");
  const int fd = hold_as_other(run);
  ASSERT_GE(fd, 0);
  try {
    RunLock l = lock_run_folder(run, "eval");
    ADD_FAILURE() << "a held folder was locked again";
  } catch (const BusyError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find(run + " is held by eval (host node7, pid 4242, since "
                              "2026-11-26T06:00:00Z)"),
              std::string::npos)
        << what;
    EXPECT_EQ(what.find('\n'), std::string::npos) << "one line";
  }
  EXPECT_EQ(test::read_text(run + "/results.json"), "{\"kept\": 1}\n");
  EXPECT_EQ(test::read_text(run + "/" + kRunLockName), kOther) << "the holder's file is untouched";
  ::close(fd);  // the other job ends: the folder is free
  RunLock mine = lock_run_folder(run, "eval");
  EXPECT_TRUE(mine.held());
}

TEST(RunLock, ALockFileWhoseHolderIsGoneIsTakenOverAndSaid) {
  TempDir dir("cdtest-lock");
  const std::string run = dir / "run";
  fs::create_directories(run);
  test::write_text(run + "/" + kRunLockName,
                   "command eval\nhost node7\npid 999999\nstarted 2026-11-26T05:00:00Z\n");
  testing::internal::CaptureStderr();
  RunLock l = lock_run_folder(run, "train");
  const std::string said = testing::internal::GetCapturedStderr();
  EXPECT_NE(said.find("taking over the lock of eval (host node7, pid 999999, since "
                      "2026-11-26T05:00:00Z), which has ended"),
            std::string::npos)
      << said;
  const std::string now = test::read_text(run + "/" + kRunLockName);
  EXPECT_NE(now.find("command train\n"), std::string::npos) << now;
  EXPECT_NE(now.find("pid " + std::to_string(::getpid()) + "\n"), std::string::npos) << now;
}

TEST(RunLock, ReleaseMarksTheFileReleasedAndRemovesAnEmptyFolderTheLockMade) {
  TempDir dir("cdtest-lock");
  const std::string fresh = dir / "a/fresh", kept = dir / "kept";
  fs::create_directories(kept);
  {
    RunLock a = lock_run_folder(fresh, "collect");
    RunLock b = lock_run_folder(kept, "eval");
    EXPECT_TRUE(fs::exists(fresh + "/" + kRunLockName));
    EXPECT_NE(test::read_text(kept + "/" + kRunLockName).find("state held\n"), std::string::npos);
  }
  EXPECT_FALSE(fs::exists(fresh)) << "a job that wrote nothing leaves no folder";
  EXPECT_TRUE(fs::exists(dir / "a"));
  EXPECT_TRUE(fs::exists(kept)) << "a folder that was there stays";
  // The lock file of a folder that stays is never removed: a job that opened it meanwhile must
  // not lock a file that no longer has the folder's name.
  const std::string released = test::read_text(kept + "/" + kRunLockName);
  EXPECT_NE(released.find("command eval\n"), std::string::npos) << released;
  EXPECT_NE(released.find("state released\n"), std::string::npos) << released;
  EXPECT_EQ(describe_lock_holder(released).rfind("eval (host ", 0), 0u);
  // A folder the lock made that holds output stays.
  {
    RunLock c = lock_run_folder(fresh, "collect");
    test::write_text(fresh + "/episode_000000.h5", "x");
  }
  EXPECT_TRUE(fs::exists(fresh + "/episode_000000.h5"));
  // A released lock is taken at once, with nothing said.
  testing::internal::CaptureStderr();
  { RunLock again = lock_run_folder(kept, "eval"); }
  EXPECT_EQ(testing::internal::GetCapturedStderr(), "");
}

TEST(RunLock, AHolderOnThisHostWhosePidIsGoneIsTakenOverAtOnce) {
  TempDir dir("cdtest-lock");
  const std::string run = dir / "run";
  fs::create_directories(run);
  test::write_text(run + "/" + kRunLockName,
                   "command eval\nhost " + host_name() + "\npid 999999\nstarted "
                   "2026-11-27T05:00:00Z\ntoken x\nbeat 7\nstate held\n");
  testing::internal::CaptureStderr();
  RunLock l = lock_run_folder(run, "train");
  const std::string said = testing::internal::GetCapturedStderr();
  EXPECT_NE(said.find("pid 999999, since 2026-11-27T05:00:00Z), which has ended"), std::string::npos)
      << said;
  EXPECT_EQ(said.find("waiting"), std::string::npos) << "no heartbeat to wait for: " << said;
}

TEST(RunLock, OneProcessNestsAndHoldsUntilTheLastRelease) {
  TempDir dir("cdtest-lock");
  const std::string run = dir / "run";
  RunLock outer = lock_run_folder(run, "train");
  {
    RunLock inner = lock_run_folder(run + "/.", "collect");  // another spelling, same folder
    EXPECT_TRUE(inner.held());
  }
  EXPECT_TRUE(fs::exists(run + "/" + kRunLockName)) << "the outer hold survives the inner";
  EXPECT_LT(hold_as_other(run), 0) << "another job is still kept out";
  outer.release();
  EXPECT_FALSE(fs::exists(run + "/" + kRunLockName));
  const int fd = hold_as_other(run);
  EXPECT_GE(fd, 0) << "free once released";
  if (fd >= 0) ::close(fd);
}

TEST(RunLock, AHolderOnThisHostThatIsAZombieIsTakenOverAtOnce) {
  // A killed job whose parent has not reaped it (a container's init may never): kill(pid, 0)
  // still succeeds on it, but it holds nothing. With flock (this host's lock, free) and
  // without it (its pid's state is read), it is taken over without waiting for a heartbeat.
  TempDir dir("cdtest-lock");
  const pid_t zombie = fork();
  ASSERT_GE(zombie, 0);
  if (zombie == 0) _exit(0);
  for (int i = 0; i < 200 && test::read_text("/proc/" + std::to_string(zombie) + "/stat")
                                         .find(") Z ") == std::string::npos;
       ++i)
    ::usleep(10000);
  ::setenv(kLockBeatEnv, "5", 1);  // a wait for the heartbeat would take 15 s
  for (bool no_flock : {false, true}) {
    if (no_flock)
      lock_testing::set_flock([](int, int) {
        errno = ENOSYS;
        return -1;
      });
    const std::string run = dir / (no_flock ? "no-flock" : "flock");
    fs::create_directories(run);
    test::write_text(run + "/" + kRunLockName,
                     "command eval\nhost " + host_name() + "\npid " + std::to_string(zombie) +
                         "\nstarted 2026-11-27T05:00:00Z\ntoken z\nbeat 3\nstate held\n");
    testing::internal::CaptureStderr();
    { RunLock l = lock_run_folder(run, "eval"); }
    const std::string said = testing::internal::GetCapturedStderr();
    EXPECT_EQ(said.find("waiting"), std::string::npos)
        << "no wait for a heartbeat (" << (no_flock ? "no flock" : "flock") << "): " << said;
    EXPECT_NE(said.find("which has ended"), std::string::npos) << said;
  }
  lock_testing::set_flock(nullptr);
  ::unsetenv(kLockBeatEnv);
  ::waitpid(zombie, nullptr, 0);
}

}  // namespace
}  // namespace cd
