#pragma once
// Running external programs (netgenerate) without a shell.
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

// This machine's host name ("unknown" when it cannot be read): lock files, MPI messages.
std::string host_name();

}  // namespace cd
