#pragma once
// Crash injection for the tests of interrupted and failed runs: a deterministic kill -9 at a
// named point, instead of a test racing the run with its own kill. No effect unless the
// environment variable is set.
//
// CAUSALDRIVE_INJECT_CRASH=<site>:<index>[:always] kills the run when it reaches <site> with
// <index>; the sites:
//   eval:<i>           eval episode i starts: its episode process dies (an infrastructure
//                      failure, which the runner retries)
//   eval-recorded:<i>  eval has written episode i's record: the command dies with its workers
//   collect:<i>        collect has committed episode i: the command dies with its workers
//   inference:<n>      batched inference's process starts its batch n (0-based): it dies alone
//   train:<n>          the training loop has committed epoch n (every method): the command dies
//                      (no marker: it dies there on every run while the variable is set)
// Without :always only the first time counts: a marker file <marker_dir>/.crash-injected-
// <site>-<index> remembers it (with no marker_dir nothing is remembered: every time counts).
// The older form <i>[:always] means eval:<i>[:always]. Several specs, comma-separated
// (eval:1:always,eval:2:always), each kill at their point.
#include <optional>
#include <string>

namespace cd {

inline constexpr const char* kInjectCrashEnv = "CAUSALDRIVE_INJECT_CRASH";

struct CrashSpec {
  std::string site;
  long index = -1;
  bool always = false;
};

// The spec of the variable's value; throws ConfigError when it is malformed.
CrashSpec parse_crash_spec(const std::string& text);

// What dies: this process, or its whole process group (kill -9 of a command and its workers;
// the tests start such commands in a group of their own).
enum class CrashScope { Process, ProcessGroup };

// Kills with SIGKILL when CAUSALDRIVE_INJECT_CRASH names this site and index (see above).
void inject_crash(const std::string& site, long index, const std::string& marker_dir,
                  CrashScope scope = CrashScope::Process);

}  // namespace cd
