#include "core/process.hpp"

#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <cerrno>
#include <cstdlib>
#include <cstdio>
#include <cstring>

#include "core/error.hpp"

extern char** environ;

namespace cd {

std::string host_name() {
  // Containers on different nodes may share one host name: CAUSALDRIVE_HOST tells them apart.
  if (const char* v = std::getenv("CAUSALDRIVE_HOST"); v != nullptr && *v != '\0') return v;
  char buf[256] = {0};
  if (gethostname(buf, sizeof buf - 1) != 0) return "unknown";
  return buf;
}

ProcessResult run_process(const std::vector<std::string>& argv,
                          const std::vector<std::string>& extra_env) {
  int fds[2];
  if (pipe(fds) != 0) throw IoError("cannot create a pipe to run " + argv.at(0));
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addclose(&actions, fds[0]);
  posix_spawn_file_actions_adddup2(&actions, fds[1], STDOUT_FILENO);
  posix_spawn_file_actions_adddup2(&actions, fds[1], STDERR_FILENO);
  posix_spawn_file_actions_addclose(&actions, fds[1]);

  std::vector<std::string> env_store = extra_env;
  for (char** e = environ; *e; ++e) env_store.emplace_back(*e);
  std::vector<char*> envp, args;
  for (auto& s : env_store) envp.push_back(s.data());
  envp.push_back(nullptr);
  std::vector<std::string> arg_store = argv;
  for (auto& s : arg_store) args.push_back(s.data());
  args.push_back(nullptr);

  pid_t pid = 0;
  int rc = posix_spawnp(&pid, args[0], &actions, nullptr, args.data(), envp.data());
  posix_spawn_file_actions_destroy(&actions);
  close(fds[1]);
  ProcessResult result;
  if (rc != 0) {
    close(fds[0]);
    result.output = std::string("cannot start ") + argv[0] + ": " + std::strerror(rc);
    return result;
  }
  std::array<char, 4096> buf;
  ssize_t n;
  while ((n = read(fds[0], buf.data(), buf.size())) > 0) result.output.append(buf.data(), n);
  close(fds[0]);
  const int status = wait_child(pid);
  if (status >= 0 && WIFEXITED(status)) result.exit_code = WEXITSTATUS(status);
  return result;
}

int wait_child(pid_t pid) {
  int status = 0;
  for (;;) {
    if (::waitpid(pid, &status, 0) == pid) return status;
    // ECHILD: the child was reaped elsewhere, or SIGCHLD is ignored (a Python host may set
    // that) and the kernel reaped it: it has ended, its status is lost.
    if (errno != EINTR) return -1;
  }
}

}  // namespace cd
