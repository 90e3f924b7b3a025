// Waiting for a child (core/process: wait_child), as the CUDA probe does: its exit status, and
// an end instead of a spin when the status cannot be had because SIGCHLD is ignored (a Python
// host may set that, and the kernel then reaps children itself: waitpid fails with ECHILD).
#include "core/process.hpp"

#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <gtest/gtest.h>

namespace cd {
namespace {

TEST(WaitChild, GivesTheChildsExitStatus) {
  const pid_t pid = fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) _exit(3);
  const int status = wait_child(pid);
  ASSERT_GE(status, 0);
  EXPECT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 3);
}

TEST(WaitChild, EndsWhenSigchldIsIgnored) {
  // In a child of its own, with an alarm: a wait that spins is killed by SIGALRM.
  const pid_t tester = fork();
  ASSERT_GE(tester, 0);
  if (tester == 0) {
    signal(SIGCHLD, SIG_IGN);
    alarm(10);
    const pid_t pid = fork();
    if (pid == 0) _exit(0);
    _exit(wait_child(pid) == -1 ? 0 : 1);
  }
  int status = 0;
  ASSERT_EQ(waitpid(tester, &status, 0), tester);
  ASSERT_FALSE(WIFSIGNALED(status)) << "the wait spun until the alarm (signal "
                                    << WTERMSIG(status) << ")";
  EXPECT_EQ(WEXITSTATUS(status), 0) << "wait_child must say the status is lost (-1)";
}

TEST(HostName, CausaldriveHostReplacesTheMachinesName) {
  ::setenv("CAUSALDRIVE_HOST", "node-b", 1);
  EXPECT_EQ(host_name(), "node-b");
  ::unsetenv("CAUSALDRIVE_HOST");
  EXPECT_NE(host_name(), "node-b");
  EXPECT_FALSE(host_name().empty());
}

}  // namespace
}  // namespace cd
