#include "core/job.hpp"

#include <chrono>
#include <filesystem>
#include <memory>

#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "core/mpi.hpp"
#include "core/progress.hpp"
#include "core/run_lock.hpp"

namespace cd {

JobResult run_job(const JobSpec& spec, const std::function<void(const JobResult&)>& summarize) {
  // 1. The folder: locked (rank 0's lock, shared by the others), its subfolders made, stale
  //    temporaries of an interrupted run removed (rank 0; the others wait), claimed.
  RunLock lock = lock_run_folder(spec.out, spec.command);
  std::vector<std::string> folders = {spec.out};
  for (const std::string& sub : spec.subfolders) {
    const std::string dir = spec.out + "/" + sub;
    std::error_code ec;
    std::filesystem::create_directories(dir, ec);
    if (ec) throw IoError("cannot create output folder " + dir + ": " + ec.message());
    folders.push_back(dir);
  }
  for (const std::string& dir : folders) remove_stale_temporaries(dir);
  if (spec.claim) mpi_lead_step(spec.claim);

  // 2. What is left.
  JobResult result;
  for (int i = 0; i < spec.total; ++i)
    if (!spec.complete || !spec.complete(i)) result.todo.push_back(i);

  // 3. The items, in workers (or here), split over the ranks.
  const auto t0 = std::chrono::steady_clock::now();
  const std::unique_ptr<Progress> progress =
      job_progress(spec.quiet, spec.label, spec.total, static_cast<long>(result.todo.size()));
  long units = 0;
  long run_now = 0;
  auto on_done = [&](int i, const std::string& note) {
    std::string line;
    units += spec.done ? spec.done(i, note, &line) : 0;
    ++run_now;
    if (progress) progress->advance(1, line);
  };
  if (spec.in_process) {
    // An error (the agent's included) ends the call; what finished before it is kept.
    if (spec.setup) spec.setup();
    for (int i : result.todo) on_done(i, spec.run(i));
  } else {
    result.pool = run_worker_pool_with_retries(spec.workers, result.todo, spec.attempts,
                                               spec.setup ? spec.setup : [] {}, spec.run,
                                               on_done, spec.after_attempt);
  }
  if (progress) progress->finish();

  // 4. The whole job's counts (collectives: every rank, in this order).
  result.units = mpi_sum(units);
  result.run_now = static_cast<int>(mpi_sum(run_now));
  result.seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (!spec.failure_what.empty() && !result.pool.failed.empty())
    throw_job_error(spec.failure_what + " failed for " +
                    std::to_string(result.pool.failed.size()) + " episode(s) (" +
                    result.pool.first_error + "); rerun the same command to resume");

  // 5. The summary, by rank 0, while the folder is still this job's.
  if (mpi_lead()) {
    lock.check();
    summarize(result);
  }
  return result;
}

}  // namespace cd
