// The run folder's lock where flock cannot be trusted (core/run_lock, docs/cluster.md): a file
// system without flock (flock made to fail with ENOSYS) and one whose flock is node-local
// (flock made to succeed for every caller, as on the other node of a BeeGFS mount). The other
// job runs on a second "host": a thread that writes the lock file as a holder on node-b would,
// beating or silent. The heartbeat period is shortened to 0.2 s.
#include "core/run_lock.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <chrono>
#include <filesystem>
#include <string>
#include <thread>

#include <gtest/gtest.h>

#include "../support/test_support.hpp"

namespace cd {
namespace {

using test::TempDir;
namespace fs = std::filesystem;

int no_flock(int, int) {
  errno = ENOSYS;
  return -1;
}
int local_flock(int, int) { return 0; }

std::string holder_text(const std::string& token, long beat, const std::string& state = "held") {
  return "command eval\nhost node-b\npid 4242\nstarted 2026-11-27T01:00:00Z\ntoken " + token +
         "\nbeat " + std::to_string(beat) + "\nstate " + state + "\n";
}

// As the lock's own writer does: the new text over the old, then cut to its length, so a reader
// never sees the file empty (truncating first left an empty file between two calls, which a
// loaded machine's reader saw now and then as "no holder" and took the live job's folder).
void write_lock(const std::string& file, const std::string& text) {
  int fd = ::open(file.c_str(), O_RDWR | O_CREAT, 0644);
  ASSERT_GE(fd, 0);
  ASSERT_EQ(::pwrite(fd, text.data(), text.size(), 0), static_cast<ssize_t>(text.size()));
  ASSERT_EQ(::ftruncate(fd, static_cast<off_t>(text.size())), 0);
  ::close(fd);
}

// A job on node-b holding `dir`: its lock file, rewritten with a new beat every 40 ms while
// `beating`.
class OtherHost {
 public:
  OtherHost(const std::string& dir, bool beating) : file_(dir + "/" + kRunLockName) {
    fs::create_directories(dir);
    write_lock(file_, holder_text("node-b:4242:feed", 0));
    if (beating)
      thread_ = std::thread([this] {
        for (long beat = 1; !stop_; ++beat) {
          std::this_thread::sleep_for(std::chrono::milliseconds(40));
          write_lock(file_, holder_text("node-b:4242:feed", beat));
        }
      });
  }
  ~OtherHost() {
    stop_ = true;
    if (thread_.joinable()) thread_.join();
  }

 private:
  std::string file_;
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

class RunLockHosts : public ::testing::TestWithParam<lock_testing::FlockFn> {
 protected:
  void SetUp() override {
    ::setenv(kLockBeatEnv, "0.2", 1);
    lock_testing::set_flock(GetParam());
  }
  void TearDown() override {
    lock_testing::set_flock(nullptr);
    ::unsetenv(kLockBeatEnv);
  }
  TempDir dir_{"cdtest-lock-hosts"};
};

TEST_P(RunLockHosts, AJobBeatingOnAnotherHostKeepsTheFolder) {
  const std::string run = dir_ / "run";
  OtherHost other(run, /*beating=*/true);
  testing::internal::CaptureStderr();
  try {
    RunLock l = lock_run_folder(run, "eval");
    ADD_FAILURE() << "a folder a live job on node-b holds was taken";
  } catch (const BusyError& e) {
    EXPECT_NE(std::string(e.what()).find(" is held by eval (host node-b, pid 4242, since "
                                         "2026-11-27T01:00:00Z)"),
              std::string::npos)
        << e.what();
  }
  const std::string said = testing::internal::GetCapturedStderr();
  EXPECT_NE(said.find("waiting up to 0.6 s for its heartbeat"), std::string::npos) << said;
  EXPECT_NE(test::read_text(run + "/" + kRunLockName).find("token node-b:4242:feed\n"),
            std::string::npos)
      << "the holder's claim is untouched";
}

TEST_P(RunLockHosts, AJobOnAnotherHostThatStoppedBeatingIsTakenOver) {
  const std::string run = dir_ / "run";
  OtherHost other(run, /*beating=*/false);
  testing::internal::CaptureStderr();
  {
    RunLock l = lock_run_folder(run, "train");
    EXPECT_TRUE(l.held());
    const std::string now = test::read_text(run + "/" + kRunLockName);
    EXPECT_NE(now.find("command train\n"), std::string::npos) << now;
    EXPECT_NE(now.find("state held\n"), std::string::npos) << now;
    EXPECT_NO_THROW(l.check());
  }
  const std::string said = testing::internal::GetCapturedStderr();
  EXPECT_NE(said.find("taking over the lock of eval (host node-b, pid 4242, since "
                      "2026-11-27T01:00:00Z), which has ended"),
            std::string::npos)
      << said;
  EXPECT_NE(test::read_text(run + "/" + kRunLockName).find("state released\n"),
            std::string::npos);
}

TEST_P(RunLockHosts, AReleasedLockIsTakenAtOnce) {
  const std::string run = dir_ / "run";
  fs::create_directories(run);
  write_lock(run + "/" + kRunLockName, holder_text("node-b:4242:feed", 9, "released"));
  testing::internal::CaptureStderr();
  RunLock l = lock_run_folder(run, "eval");
  EXPECT_EQ(testing::internal::GetCapturedStderr(), "") << "nothing to wait for or take over";
}

TEST_P(RunLockHosts, TheHolderBeatsAndAJobThatTakesItOverIsNoticed) {
  const std::string run = dir_ / "run";
  fs::create_directories(run);
  test::write_text(run + "/results.json", "{}\n");
  const std::string file = run + "/" + kRunLockName;
  testing::internal::CaptureStderr();
  {
    RunLock mine = lock_run_folder(run, "eval");
    std::this_thread::sleep_for(std::chrono::milliseconds(700));
    const std::string beaten = test::read_text(file);
    EXPECT_EQ(beaten.find("beat 0\n"), std::string::npos) << "the heartbeat advances: " << beaten;
    EXPECT_NO_THROW(mine.check());
    // node-b judged this job dead and took the folder.
    write_lock(file, holder_text("node-b:4242:feed", 0));
    std::this_thread::sleep_for(std::chrono::milliseconds(500));
    EXPECT_THROW(mine.check(), BusyError);
    try {
      mine.check();
    } catch (const BusyError& e) {
      EXPECT_NE(std::string(e.what()).find("was taken over by eval (host node-b"),
                std::string::npos)
          << e.what();
    }
  }
  const std::string said = testing::internal::GetCapturedStderr();
  EXPECT_NE(said.find("the lock was taken over by eval (host node-b"), std::string::npos) << said;
  EXPECT_EQ(test::read_text(file), holder_text("node-b:4242:feed", 0))
      << "the new holder's claim is neither overwritten nor released";
  EXPECT_EQ(test::read_text(run + "/results.json"), "{}\n");
}

INSTANTIATE_TEST_SUITE_P(FileSystems, RunLockHosts,
                         ::testing::Values(&no_flock, &local_flock),
                         [](const auto& info) {
                           return std::string(info.index == 0 ? "NoFlock" : "NodeLocalFlock");
                         });

TEST(RunLockNoFlock, OfTwoClaimsAtOnceTheOverwrittenOneBacksOff) {
  ::setenv(kLockBeatEnv, "0.4", 1);
  lock_testing::set_flock(&no_flock);
  TempDir dir("cdtest-lock-hosts");
  const std::string run = dir / "run";
  fs::create_directories(run);
  const std::string file = run + "/" + kRunLockName;
  // node-b writes its claim right after ours, inside our settling quarter period. It polls
  // from before our claim creates the file, so a missing file reads as empty here.
  auto read_if_there = [&] {
    std::error_code ec;
    return fs::exists(file, ec) ? test::read_text(file) : std::string();
  };
  std::atomic<bool> stop{false};
  std::thread other([&] {
    while (!stop) {
      const std::string now = read_if_there();
      if (now.find("state held") != std::string::npos &&
          now.find("node-b") == std::string::npos) {
        write_lock(file, holder_text("node-b:4242:feed", 0));
        return;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
  });
  EXPECT_THROW(lock_run_folder(run, "eval"), BusyError);
  stop = true;
  other.join();
  EXPECT_EQ(test::read_text(file), holder_text("node-b:4242:feed", 0));
  lock_testing::set_flock(nullptr);
  ::unsetenv(kLockBeatEnv);
}

TEST(RunLockBeat, AMalformedPeriodIsOneLine) {
  ::setenv(kLockBeatEnv, "soon", 1);
  EXPECT_THROW(lock_beat_seconds(), ConfigError);
  ::setenv(kLockBeatEnv, "0", 1);
  EXPECT_THROW(lock_beat_seconds(), ConfigError);
  ::unsetenv(kLockBeatEnv);
  EXPECT_EQ(lock_beat_seconds(), 10.0);
}

}  // namespace
}  // namespace cd
