#pragma once
// Episodes in parallel worker processes (libsumo runs one simulation per process). Each
// worker prepares itself once (loads the network), then runs every job of its share in a
// fresh fork of itself: every job starts from the same process state, whatever ran before,
// and a crash costs one job, not the worker. A killed parent takes its workers along.
#include <functional>
#include <map>
#include <string>
#include <vector>

namespace cd {

struct PoolReport {
  std::vector<int> failed;    // jobs that threw, crashed or never reported
  std::string first_error;    // "job N: what happened" of the first failure
  // Each failed job's own line ("job N: what happened"; under MPI with "rank R of S on HOST: "
  // before it, the rank where it ran), or the worker's when the job never said (a crash).
  std::map<int, std::string> errors;
  const std::string& error_of(int job) const {
    auto it = errors.find(job);
    return it == errors.end() ? first_error : it->second;
  }
};

// Runs job(i) for every i in `todo` on up to `workers` processes. `setup` runs once in each
// worker before its first job; `job` runs in a fork of the worker and returns a one-line note
// (or throws); on_done(i, note) is called in this process as jobs finish.
PoolReport run_worker_pool(int workers, const std::vector<int>& todo,
                           const std::function<void()>& setup,
                           const std::function<std::string(int)>& job,
                           const std::function<void(int, const std::string&)>& on_done);

// In a worker of run_worker_pool (and the forks of its jobs): its number, 0 to workers - 1;
// -1 in any other process.
int worker_index();

// run_worker_pool up to `attempts` times: a job whose worker crashed (the infrastructure's
// fault, not the job's) is run again. `failed` lists what still failed after the last
// attempt; first_error is the last attempt's first error that was seen.
// Under MPI (core/mpi.hpp) every rank calls it: rank 0's `todo` is split over the ranks (one
// worker each), and every rank returns the whole job's failures, each error naming the rank and
// host where it happened; on_done sees this rank's jobs only. `after_attempt`, when set, runs
// here after each attempt and may throw to stop the job (a dead inference process).
PoolReport run_worker_pool_with_retries(
    int workers, const std::vector<int>& todo, int attempts, const std::function<void()>& setup,
    const std::function<std::string(int)>& job,
    const std::function<void(int, const std::string&)>& on_done,
    const std::function<void()>& after_attempt = {});

}  // namespace cd
