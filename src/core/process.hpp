#pragma once
// Running external programs (netgenerate) without a shell.
#include <sys/types.h>

#include <string>
#include <vector>

namespace cd {

struct ProcessResult {
  int exit_code = -1;   // -1 when it died from a signal or could not start
  std::string output;   // stdout and stderr together
};

// Runs argv[0] (searched in PATH) with extra environment entries "K=V"; waits for it.
ProcessResult run_process(const std::vector<std::string>& argv,
                          const std::vector<std::string>& extra_env = {});

// Waits for child `pid` (retrying when interrupted): its wait status, or -1 when it cannot be
// had (ECHILD: reaped elsewhere, or SIGCHLD ignored by the host process; the child has ended).
int wait_child(pid_t pid);

// This machine's host name ("unknown" when it cannot be read): lock files, MPI messages,
// temporary names. CAUSALDRIVE_HOST, when set, replaces it (containers on several nodes that
// share one name).
std::string host_name();

}  // namespace cd
