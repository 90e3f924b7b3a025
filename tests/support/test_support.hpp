#pragma once
// Shared helpers of the unit and e2e tests (header-only): temporary folders, running the built
// binary with its output captured, small files, the fast test config.
//
// Every test file that includes this header points CAUSALDRIVE_CACHE at one folder shared by
// all test processes (ctest runs each test in its own process), so the generated towns are
// built once and then reused; generation is atomic, so parallel ctest jobs are safe.
#include <fcntl.h>
#include <signal.h>
#include <sys/stat.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "core/build_parts.hpp"

// A test that needs an optional part of the build (docs/gpu.md) starts with one of these: in a
// build without that part it is skipped, saying why. (A test file that cannot even compile
// without the part says "// needs: PART" in its first lines instead; CMake leaves it out.)
#define CD_NEEDS_SUMO()                                                                 \
  do {                                                                                  \
    if (!::cd::built_with_sumo()) GTEST_SKIP() << "needs SUMO (-DCD_WITH_SUMO=OFF)";    \
  } while (0)
#define CD_NEEDS_MUJOCO()                                                                   \
  do {                                                                                      \
    if (!::cd::built_with_mujoco()) GTEST_SKIP() << "needs MuJoCo (-DCD_WITH_MUJOCO=OFF)";  \
  } while (0)

namespace cd::test {

namespace fs = std::filesystem;

// The town cache shared by all test processes of this user.
inline std::string shared_cache_dir() {
  return (fs::temp_directory_path() / ("causaldrive-test-cache-" + std::to_string(::getuid())))
      .string();
}

// Runs before main() in every test binary that includes this header (and is inherited by the
// CLI processes the tests start).
inline const bool kCacheEnvSet = [] {
  ::setenv("CAUSALDRIVE_CACHE", shared_cache_dir().c_str(), 1);
  return true;
}();

// A fresh folder under the system temp dir, removed with everything in it on destruction
// (kept when CD_TEST_KEEP_TMP is set, for debugging).
class TempDir {
 public:
  explicit TempDir(const std::string& tag = "cdtest") {
    std::string tmpl = (fs::temp_directory_path() / (tag + "-XXXXXX")).string();
    std::vector<char> buf(tmpl.begin(), tmpl.end());
    buf.push_back('\0');
    if (!::mkdtemp(buf.data())) throw std::runtime_error("mkdtemp failed for " + tmpl);
    path_ = buf.data();
  }
  ~TempDir() {
    if (std::getenv("CD_TEST_KEEP_TMP")) return;
    std::error_code ec;
    fs::remove_all(path_, ec);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;

  const std::string& path() const { return path_; }
  std::string operator/(const std::string& name) const { return path_ + "/" + name; }

 private:
  std::string path_;
};

// Sets an environment variable (inherited by the commands a test starts) for its lifetime.
class ScopedEnv {
 public:
  ScopedEnv(const std::string& name, const std::string& value) : name_(name) {
    if (const char* old = std::getenv(name.c_str())) old_ = old, had_ = true;
    ::setenv(name.c_str(), value.c_str(), 1);
  }
  ~ScopedEnv() {
    if (had_) ::setenv(name_.c_str(), old_.c_str(), 1);
    else ::unsetenv(name_.c_str());
  }
  ScopedEnv(const ScopedEnv&) = delete;
  ScopedEnv& operator=(const ScopedEnv&) = delete;

 private:
  std::string name_, old_;
  bool had_ = false;
};

inline void write_text(const std::string& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (!out) throw std::runtime_error("cannot write " + path);
  out << text;
}

inline std::string read_text(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error("cannot read " + path);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

// Whether a run folder's lock file says its job released it (core/run_lock never removes the
// file of a folder that stays).
inline bool lock_released(const std::string& dir) {
  return read_text(dir + "/causaldrive.lock").find("\nstate released\n") != std::string::npos;
}

inline std::vector<std::string> split_lines(const std::string& text) {
  std::vector<std::string> lines;
  std::istringstream in(text);
  std::string line;
  while (std::getline(in, line)) lines.push_back(line);
  return lines;
}

inline bool starts_with(const std::string& s, const std::string& prefix) {
  return s.rfind(prefix, 0) == 0;
}

inline bool ends_with(const std::string& s, const std::string& suffix) {
  return s.size() >= suffix.size() &&
         s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

// File names (not paths) in a folder, sorted.
inline std::vector<std::string> list_dir(const std::string& dir) {
  std::vector<std::string> names;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(dir, ec)) names.push_back(e.path().filename().string());
  std::sort(names.begin(), names.end());
  return names;
}

struct CommandResult {
  bool exited = false;    // normal exit (not a signal)
  int exit_code = -1;     // when exited
  int signal = 0;         // when killed by a signal
  bool core_dumped = false;
  bool timed_out = false;
  std::string out, err;   // captured stdout and stderr

  std::string describe() const {
    std::ostringstream s;
    if (timed_out) s << "timed out; ";
    if (exited) s << "exit code " << exit_code;
    else s << "killed by signal " << signal << (core_dumped ? " (core dumped)" : "");
    s << "\n--- stdout ---\n" << out << "\n--- stderr ---\n" << err;
    return s.str();
  }
};

namespace detail {

[[noreturn]] inline void exec_child(const std::vector<std::string>& argv, const std::string& cwd) {
  if (!cwd.empty() && ::chdir(cwd.c_str()) != 0) ::_exit(126);
  std::vector<char*> args;
  for (const auto& a : argv) args.push_back(const_cast<char*>(a.c_str()));
  args.push_back(nullptr);
  ::execv(args[0], args.data());
  ::_exit(127);
}

inline int open_out(const std::string& path) {
  return ::open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
}

// In a forked child: stdin from /dev/null, stdout and stderr to files, then exec.
[[noreturn]] inline void redirect_and_exec(const std::vector<std::string>& argv,
                                           const std::string& cwd, const std::string& out_path,
                                           const std::string& err_path) {
  int in = ::open("/dev/null", O_RDONLY);
  int out = open_out(out_path), err = open_out(err_path);
  if (in < 0 || out < 0 || err < 0) ::_exit(126);
  ::dup2(in, 0);
  ::dup2(out, 1);
  ::dup2(err, 2);
  exec_child(argv, cwd);
}

}  // namespace detail

// Waits up to timeout_s for the child `pid` to end: true with its wait status in *status, false
// while it still runs (the caller kills it).
inline bool wait_child(pid_t pid, double timeout_s, int* status) {
  const auto deadline =
      std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
  while (true) {
    const pid_t w = ::waitpid(pid, status, WNOHANG);
    if (w == pid) return true;
    if (w < 0) throw std::runtime_error("waitpid failed");
    if (std::chrono::steady_clock::now() > deadline) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
}

// Runs argv (argv[0] an absolute path) with stdin from /dev/null and stdout/stderr captured
// through files; kills it after timeout_s. cwd: the folder to run in (empty: the current one).
// The command runs in a process group of its own: a crash injected into it that kills its
// whole group (core/fault.hpp) never reaches the test, and a timeout kills its workers too.
inline CommandResult run_command(const std::vector<std::string>& argv, const std::string& cwd = "",
                                 double timeout_s = 300) {
  TempDir io("cdtest-io");
  const std::string out_path = io / "stdout", err_path = io / "stderr";
  std::fflush(nullptr);
  pid_t pid = ::fork();
  if (pid < 0) throw std::runtime_error("fork failed");
  if (pid == 0) {
    ::setpgid(0, 0);
    detail::redirect_and_exec(argv, cwd, out_path, err_path);
  }
  ::setpgid(pid, pid);  // also from the parent, so the group exists before any kill
  CommandResult r;
  int status = 0;
  if (!wait_child(pid, timeout_s, &status)) {
    r.timed_out = true;
    ::kill(-pid, SIGKILL);
    ::waitpid(pid, &status, 0);
  }
  r.exited = WIFEXITED(status);
  if (r.exited) r.exit_code = WEXITSTATUS(status);
  if (WIFSIGNALED(status)) {
    r.signal = WTERMSIG(status);
#ifdef WCOREDUMP
    r.core_dumped = WCOREDUMP(status);
#endif
  }
  r.out = read_text(out_path);
  r.err = read_text(err_path);
  return r;
}

// The causaldrive binary with arguments.
inline CommandResult run_cli(const std::vector<std::string>& args, const std::string& cwd = "",
                             double timeout_s = 300) {
  std::vector<std::string> argv = {CD_BINARY};
  argv.insert(argv.end(), args.begin(), args.end());
  return run_command(argv, cwd, timeout_s);
}

// Starts argv in the background in its own process group (pgid == pid), output to files.
inline pid_t spawn_group(const std::vector<std::string>& argv, const std::string& out_path,
                         const std::string& err_path) {
  std::fflush(nullptr);
  pid_t pid = ::fork();
  if (pid < 0) throw std::runtime_error("fork failed");
  if (pid == 0) {
    ::setpgid(0, 0);
    detail::redirect_and_exec(argv, "", out_path, err_path);
  }
  ::setpgid(pid, pid);  // also from the parent, so kill(-pid) works at once
  return pid;
}

// Runs a Python script with the oracle interpreter (h5py, numpy); args follow the script.
inline CommandResult run_python(const std::string& script, const std::vector<std::string>& args,
                                const TempDir& dir) {
  const std::string path = dir / "oracle.py";
  write_text(path, script);
  std::vector<std::string> argv = {CD_PYTHON, path};
  argv.insert(argv.end(), args.begin(), args.end());
  return run_command(argv);
}

// A fast config for tests: town-a, short warm-up, short routes, few small episodes.
// `traffic`: empty | regular | dense. `extra` is appended verbatim (more tables). The routes
// collected are min_route_m to max_route_m long.
inline std::string test_config_toml(const std::string& traffic = "empty",
                                    const std::string& extra = "", int min_route_m = 100,
                                    int max_route_m = 200) {
  std::string t;
  t += "# written by the causaldrive tests\n";
  t += "[world]\n";
  t += "town = \"town-a\"\n";
  t += "traffic = \"" + traffic + "\"\n";
  t += "warmup_s = 5\n";
  t += "\n[collect]\n";
  t += "episodes = 2\n";
  t += "workers = 1\n";
  t += "min_route_m = " + std::to_string(min_route_m) + "\n";
  t += "max_route_m = " + std::to_string(max_route_m) + "\n";
  t += extra;
  return t;
}

// Writes the test config into `dir` and returns its path.
inline std::string write_test_config(const TempDir& dir, const std::string& traffic = "empty",
                                     const std::string& extra = "",
                                     const std::string& name = "test.toml") {
  const std::string path = dir / name;
  write_text(path, test_config_toml(traffic, extra));
  return path;
}

}  // namespace cd::test
