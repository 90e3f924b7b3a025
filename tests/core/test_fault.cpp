// The crash-injection hook of the kill-and-resume tests (core/fault): its spec, and that it
// kills exactly at its site and index, once or always.
#include "core/fault.hpp"

#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <string>

#include "../support/test_support.hpp"
#include "core/error.hpp"

namespace cd {
namespace {

using test::TempDir;

TEST(CrashSpec, SiteIndexAndAlways) {
  CrashSpec a = parse_crash_spec("collect:3");
  EXPECT_EQ(a.site, "collect");
  EXPECT_EQ(a.index, 3);
  EXPECT_FALSE(a.always);
  CrashSpec b = parse_crash_spec("eval-recorded:12:always");
  EXPECT_EQ(b.site, "eval-recorded");
  EXPECT_EQ(b.index, 12);
  EXPECT_TRUE(b.always);
  // The older eval-only form.
  CrashSpec c = parse_crash_spec("2:always");
  EXPECT_EQ(c.site, "eval");
  EXPECT_EQ(c.index, 2);
  EXPECT_TRUE(c.always);
  EXPECT_EQ(parse_crash_spec("7").site, "eval");
  for (const char* bad : {"", "train", "train:", ":3", "train:x", "train:-1", "train:1:twice"})
    EXPECT_THROW(parse_crash_spec(bad), ConfigError) << bad;
}

// Calls inject_crash in a child process (in a process group of its own, so that the group
// scope cannot reach this test) and tells how the child ended: the signal, or 0 for an exit.
int crash_in_child(const char* spec, const std::string& site, long index,
                   const std::string& marker_dir, CrashScope scope) {
  std::fflush(nullptr);
  pid_t pid = ::fork();
  if (pid == 0) {
    ::setpgid(0, 0);
    ::setenv(kInjectCrashEnv, spec, 1);
    inject_crash(site, index, marker_dir, scope);
    ::_exit(0);
  }
  int status = 0;
  ::waitpid(pid, &status, 0);
  return WIFSIGNALED(status) ? WTERMSIG(status) : 0;
}

TEST(InjectCrash, KillsAtItsSiteOnceWithAMarker) {
  TempDir dir("cdtest-fault");
  const auto P = CrashScope::Process, G = CrashScope::ProcessGroup;
  EXPECT_EQ(crash_in_child("collect:1", "collect", 0, dir.path(), G), 0);
  EXPECT_EQ(crash_in_child("collect:1", "train", 1, dir.path(), G), 0);
  EXPECT_EQ(crash_in_child("collect:1", "collect", 1, dir.path(), G), SIGKILL);
  EXPECT_TRUE(test::fs::exists(dir / ".crash-injected-collect-1"));
  EXPECT_EQ(crash_in_child("collect:1", "collect", 1, dir.path(), G), 0) << "only once";
  EXPECT_EQ(crash_in_child("eval:2:always", "eval", 2, dir.path(), P), SIGKILL);
  EXPECT_EQ(crash_in_child("eval:2:always", "eval", 2, dir.path(), P), SIGKILL);
  EXPECT_FALSE(test::fs::exists(dir / ".crash-injected-eval-2"));
  // No marker folder: nothing is remembered.
  EXPECT_EQ(crash_in_child("train:3", "train", 3, "", P), SIGKILL);
  EXPECT_EQ(crash_in_child("train:3", "train", 3, "", P), SIGKILL);
  // Unset: never.
  ::unsetenv(kInjectCrashEnv);
  EXPECT_NO_FATAL_FAILURE(inject_crash("train", 3, "", P));
}

}  // namespace
}  // namespace cd
