#include "collect/collect.hpp"

#include <sys/prctl.h>
#include <sys/wait.h>

#include <csignal>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <map>
#include <memory>
#include <sstream>

#include <nlohmann/json.hpp>

#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "core/progress.hpp"
#include "data/h5_episode.hpp"
#include "world/town.hpp"

namespace fs = std::filesystem;

namespace cd {

namespace {

constexpr int kMaxAttempts = 2;  // a worker that dies is retried once per episode

bool episode_complete(const std::string& path) {
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) return false;
  try {
    read_episode_meta(path);
    return true;
  } catch (const Error&) {
    return false;  // a damaged file is recorded again
  }
}

// Leftovers of interrupted runs: temporary files never carry a final name, so they can go.
void remove_stale_temporaries(const std::string& dir) {
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(dir, ec)) {
    const std::string name = e.path().filename().string();
    if (name.size() > 4 && name.compare(name.size() - 4, 4, ".tmp") == 0) fs::remove(e.path(), ec);
  }
}

// Runs in a worker: loads the network once, then records each episode in a fork of itself,
// so that every episode starts from the same process state (SUMO keeps some state across
// reloads) and a crash costs one episode, not the worker.
[[noreturn]] void worker_main(const Settings& settings, const std::vector<int>& indices,
                              const CollectOptions& options, int fd) {
  auto report = [fd](const std::string& line) {
    std::string l = line + "\n";
    ssize_t ignored = write(fd, l.data(), l.size());
    (void)ignored;
  };
  auto fail = [&](int index, std::string msg) {
    std::replace(msg.begin(), msg.end(), '\n', ' ');
    report("error " + std::to_string(index) + " " + msg);
  };
  std::unique_ptr<World> world;
  try {
    world = std::make_unique<World>(settings);
  } catch (const std::exception& e) {
    fail(indices.empty() ? -1 : indices.front(), e.what());
    _exit(1);
  }
  int failures = 0;
  for (int i : indices) {
    std::fflush(nullptr);
    pid_t pid = fork();
    if (pid < 0) {
      fail(i, "cannot fork: " + std::string(std::strerror(errno)));
      _exit(1);
    }
    if (pid == 0) {
      prctl(PR_SET_PDEATHSIG, SIGKILL);
      try {
        ExpertRecorder recorder(*world, settings);
        EpisodeData data;
        EpisodeMeta meta;
        std::string png = options.png_dir.empty()
                              ? ""
                              : options.png_dir + "/" + fs::path(episode_file_name(i)).stem().string();
        EpisodeSummary s = recorder.run(i, episode_seed(settings.collect.seed, i), data, meta, png);
        write_episode(settings.collect.out + "/" + episode_file_name(i), meta, data);
        report("done " + std::to_string(i) + " " + std::to_string(s.frames) + " " + s.outcome);
        _exit(0);
      } catch (const std::exception& e) {
        fail(i, e.what());
        _exit(1);
      }
    }
    int status = 0;
    waitpid(pid, &status, 0);
    if (WIFSIGNALED(status)) fail(i, "crashed with signal " + std::to_string(WTERMSIG(status)));
    if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) ++failures;
  }
  close(fd);
  _exit(failures == 0 ? 0 : 1);
}

struct WorkerRun {
  std::vector<int> failed;       // episodes not recorded
  std::string first_error;
};

WorkerRun run_workers(const Settings& settings, const std::vector<int>& todo,
                      const CollectOptions& options, Progress* progress, long* frames) {
  int k = std::max(1, std::min<int>(settings.collect.workers, static_cast<int>(todo.size())));
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
      // A killed parent takes its workers along: no orphan keeps writing into the folder.
      prctl(PR_SET_PDEATHSIG, SIGKILL);
      if (getppid() != parent) _exit(1);
      close(fds[0]);
      worker_main(settings, mine, options, fds[1]);
    }
    pids.push_back(pid);
  }
  close(fds[1]);

  WorkerRun result;
  std::map<int, bool> done;
  std::string pending;
  char buf[4096];
  ssize_t n;
  while ((n = read(fds[0], buf, sizeof buf)) > 0) {
    pending.append(buf, n);
    size_t nl;
    while ((nl = pending.find('\n')) != std::string::npos) {
      std::istringstream line(pending.substr(0, nl));
      pending.erase(0, nl + 1);
      std::string kind;
      int idx;
      line >> kind >> idx;
      if (kind == "done") {
        long f;
        std::string outcome;
        line >> f >> outcome;
        *frames += f;
        done[idx] = true;
        if (progress) progress->advance(1, "episode " + std::to_string(idx) + ": " + outcome);
      } else if (kind == "error" && result.first_error.empty()) {
        std::string rest;
        std::getline(line, rest);
        result.first_error = "episode " + std::to_string(idx) + ":" + rest;
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
  return result;
}

}  // namespace

std::string episode_file_name(int index) {
  char name[32];
  std::snprintf(name, sizeof name, "episode_%06d.h5", index);
  return name;
}

CollectReport collect(const Settings& settings, const CollectOptions& options) {
  resolve_network(settings.world.town);  // a bad town is one clear error, not one per worker
  const std::string& out = settings.collect.out;
  std::error_code ec;
  fs::create_directories(out, ec);
  if (ec) throw IoError("cannot create output folder " + out + ": " + ec.message());
  remove_stale_temporaries(out);

  std::vector<int> todo;
  for (int i = 0; i < settings.collect.episodes; ++i)
    if (!episode_complete(out + "/" + episode_file_name(i))) todo.push_back(i);

  CollectReport report;
  auto t0 = std::chrono::steady_clock::now();
  int total = settings.collect.episodes;
  std::unique_ptr<Progress> progress;
  if (!options.quiet) progress = std::make_unique<Progress>("collect", total, total - (long)todo.size());
  std::vector<int> remaining = todo;
  std::string error;
  for (int attempt = 0; attempt < kMaxAttempts && !remaining.empty(); ++attempt) {
    WorkerRun run = run_workers(settings, remaining, options, progress.get(), &report.frames);
    if (!run.first_error.empty()) error = run.first_error;
    remaining = run.failed;
  }
  if (progress) progress->finish();
  report.recorded_now = static_cast<int>(todo.size() - remaining.size());
  report.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (!remaining.empty()) {
    throw Error("collection failed for " + std::to_string(remaining.size()) + " episode(s) (" +
                error + "); rerun the same command to resume");
  }

  nlohmann::json summary = nlohmann::json::array();
  for (int i = 0; i < total; ++i) {
    EpisodeMeta m = read_episode_meta(out + "/" + episode_file_name(i));
    EpisodeSummary s;
    s.index = i;
    s.outcome = m.outcome;
    auto get = [&](const char* k) {
      auto it = m.extra.find(k);
      return it == m.extra.end() ? std::string() : it->second;
    };
    s.route_length = std::atof(get("route_length_m").c_str());
    s.distance = std::atof(get("distance_m").c_str());
    s.red_light_violations = std::atoi(get("red_light_violations").c_str());
    s.collided_with = get("collided_with");
    report.episodes.push_back(s);
    summary.push_back({{"file", episode_file_name(i)},
                       {"outcome", s.outcome},
                       {"route_length_m", s.route_length},
                       {"distance_m", s.distance},
                       {"red_light_violations", s.red_light_violations},
                       {"collided_with", s.collided_with},
                       {"seed", m.seed}});
  }
  nlohmann::json manifest = {{"settings", settings_to_json(settings)}, {"episodes", summary}};
  write_file_atomic(out + "/collect.json", manifest.dump(2) + "\n");
  return report;
}

}  // namespace cd
