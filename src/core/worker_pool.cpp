#include "core/worker_pool.hpp"

#include <sys/prctl.h>
#include <sys/wait.h>
#include <limits.h>
#include <unistd.h>

#include <algorithm>
#include <csignal>
#include <cstdlib>
#include <cstdio>
#include <cstring>
#include <map>
#include <sstream>

#include "core/error.hpp"
#include "core/mpi.hpp"

namespace cd {

namespace {

int this_worker = -1;  // worker_index()

void send_line(int fd, std::string line) {
  std::replace(line.begin(), line.end(), '\n', ' ');
  line += "\n";
  // One write per line: lines of different workers never interleave (PIPE_BUF).
  ssize_t ignored = write(fd, line.data(), std::min<size_t>(line.size(), PIPE_BUF));
  (void)ignored;
}

[[noreturn]] void worker_main(const std::vector<int>& mine, const std::function<void()>& setup,
                              const std::function<std::string(int)>& job, int fd) {
  try {
    setup();
  } catch (const std::exception& e) {
    send_line(fd, "error " + std::to_string(mine.empty() ? -1 : mine.front()) + " " + e.what());
    _exit(1);
  }
  int failures = 0;
  for (int i : mine) {
    std::fflush(nullptr);
    pid_t pid = fork();
    if (pid < 0) {
      send_line(fd, "error " + std::to_string(i) + " cannot fork: " + std::strerror(errno));
      _exit(1);
    }
    if (pid == 0) {
      prctl(PR_SET_PDEATHSIG, SIGKILL);
      try {
        std::string note = job(i);
        std::fflush(nullptr);
        send_line(fd, "done " + std::to_string(i) + " " + note);
        _exit(0);
      } catch (const std::exception& e) {
        send_line(fd, "error " + std::to_string(i) + " " + e.what());
        _exit(1);
      }
    }
    int status = 0;
    waitpid(pid, &status, 0);
    if (WIFSIGNALED(status))
      send_line(fd, "error " + std::to_string(i) + " crashed with signal " +
                        std::to_string(WTERMSIG(status)));
    if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) ++failures;
  }
  close(fd);
  _exit(failures == 0 ? 0 : 1);
}

}  // namespace

int worker_index() { return this_worker; }

PoolReport run_worker_pool(int workers, const std::vector<int>& todo,
                           const std::function<void()>& setup,
                           const std::function<std::string(int)>& job,
                           const std::function<void(int, const std::string&)>& on_done) {
  PoolReport result;
  if (todo.empty()) return result;
  int k = std::max(1, std::min<int>(workers, static_cast<int>(todo.size())));
  int fds[2];
  if (pipe(fds) != 0) throw IoError("cannot create a pipe for the workers");
  std::fflush(nullptr);
  std::vector<pid_t> pids;
  const pid_t parent = getpid();
  for (int w = 0; w < k; ++w) {
    std::vector<int> mine;
    for (size_t j = w; j < todo.size(); j += k) mine.push_back(todo[j]);
    pid_t pid = fork();
    if (pid < 0) throw Error("cannot start a worker process: " + std::string(std::strerror(errno)));
    if (pid == 0) {
      prctl(PR_SET_PDEATHSIG, SIGKILL);
      if (getppid() != parent) _exit(1);
      close(fds[0]);
      this_worker = w;
      worker_main(mine, setup, job, fds[1]);
    }
    pids.push_back(pid);
  }
  close(fds[1]);

  std::map<int, bool> done;
  std::string pending;
  char buf[4096];
  ssize_t n;
  while ((n = read(fds[0], buf, sizeof buf)) > 0) {
    pending.append(buf, n);
    size_t nl;
    while ((nl = pending.find('\n')) != std::string::npos) {
      std::string line = pending.substr(0, nl);
      pending.erase(0, nl + 1);
      std::istringstream in(line);
      std::string kind;
      int idx = -1;
      in >> kind >> idx;
      std::string rest;
      std::getline(in, rest);
      if (!rest.empty() && rest[0] == ' ') rest.erase(0, 1);
      if (kind == "done") {
        done[idx] = true;
        on_done(idx, rest);
      } else if (kind == "error") {
        const std::string line = "job " + std::to_string(idx) + ": " + rest;
        if (result.first_error.empty()) result.first_error = line;
        if (idx >= 0) result.errors[idx] = line;
      }
    }
  }
  close(fds[0]);
  for (pid_t pid : pids) {
    int status = 0;
    waitpid(pid, &status, 0);
    if (WIFSIGNALED(status) && result.first_error.empty())
      result.first_error = "a worker was killed by signal " + std::to_string(WTERMSIG(status));
  }
  for (int i : todo)
    if (!done.count(i)) result.failed.push_back(i);
  for (auto it = result.errors.begin(); it != result.errors.end();)
    it = done.count(it->first) ? result.errors.erase(it) : std::next(it);
  for (int i : result.failed)  // a job that never said why (its worker died): the worker's line
    if (!result.errors.count(i) && !result.first_error.empty())
      result.errors[i] = result.first_error;
  return result;
}

PoolReport run_worker_pool_with_retries(
    int workers, const std::vector<int>& todo, int attempts, const std::function<void()>& setup,
    const std::function<std::string(int)>& job,
    const std::function<void(int, const std::string&)>& on_done,
    const std::function<void()>& after_attempt) {
  PoolReport report;
  report.failed = todo;
  if (mpi_distributed()) {
    // Rank 0's list (what it found still to do), every size-th job of it on this rank, in one
    // world (one worker); then every rank learns what failed where.
    const std::vector<int> all = mpi_broadcast(todo);
    const MpiPlace& p = mpi_place();
    report.failed.clear();
    for (size_t j = static_cast<size_t>(p.rank); j < all.size(); j += static_cast<size_t>(p.size))
      report.failed.push_back(all[j]);
    workers = 1;
  }
  for (int attempt = 0; attempt < attempts && !report.failed.empty(); ++attempt) {
    PoolReport run = run_worker_pool(workers, report.failed, setup, job, on_done);
    if (after_attempt) after_attempt();
    if (!run.first_error.empty()) report.first_error = run.first_error;
    report.failed = run.failed;
    report.errors = run.errors;  // the last attempt's, of what still failed
  }
  if (mpi_distributed()) {
    // Every rank's failures with their own lines, each named by the rank where it happened:
    // one text per rank, "N<tab>line" per failed job.
    const std::string where = mpi_where() + ": ";
    std::string mine;
    for (int i : report.failed) mine += std::to_string(i) + "\t" + where + report.error_of(i) + "\n";
    const std::vector<std::string> texts = mpi_all_gather(mine);
    const std::vector<std::string> firsts =
        mpi_all_gather(report.first_error.empty() ? "" : where + report.first_error);
    report = PoolReport{};
    for (const std::string& e : firsts)
      if (report.first_error.empty() && !e.empty()) report.first_error = e;
    for (const std::string& text : texts) {
      std::istringstream in(text);
      for (std::string line; std::getline(in, line);) {
        const size_t tab = line.find('\t');
        const int i = std::atoi(line.substr(0, tab).c_str());
        report.failed.push_back(i);
        report.errors[i] = line.substr(tab + 1);
      }
    }
    std::sort(report.failed.begin(), report.failed.end());
  }
  return report;
}

}  // namespace cd
