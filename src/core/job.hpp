#pragma once
// The one sequence of a job that writes episodes into a run folder (collect and eval, driving
// and MuJoCo-Image): lock the folder, remove stale temporaries, claim it, list what is left,
// run it in worker processes (split over MPI ranks), sum the counts over the ranks, and let
// rank 0 write the summary while the lock is still held. Under MPI every rank must make the
// same collective calls in the same order; this file is the only place that orders them.
#include <functional>
#include <map>
#include <string>
#include <vector>

#include "core/worker_pool.hpp"

namespace cd {

struct JobSpec {
  std::string command;  // "collect" | "eval": the lock file's holder line
  std::string out;      // the run folder: created, locked, cleaned of stale temporaries
  std::vector<std::string> subfolders;  // created under `out` and cleaned too ("episodes")
  // After the lock, on rank 0 alone (its error stops every rank): the folder's claim (eval's
  // run.json). May be empty.
  std::function<void()> claim;
  int total = 0;                         // items 0..total-1
  std::function<bool(int)> complete;     // is item i already in the folder (called per item)
  std::string label;                     // progress label ("eval bc-oh on town-a-regular")
  bool quiet = false;
  int workers = 1;
  int attempts = 1;                      // a job whose worker crashed is run again
  bool in_process = false;               // one after another here (a Python agent): no fork
  std::function<void()> setup;           // once per worker before its first item (may be empty)
  std::function<std::string(int)> run;   // item i in a fork of the worker: its one-line note
  // After each attempt of the workers (not in process): may throw to stop the job before its
  // summary (batched inference's check that its inference process still runs).
  std::function<void()> after_attempt;
  // Item i finished (this rank's items, in this process): the units its note counts (frames,
  // steps) and the progress note.
  std::function<long(int, const std::string&, std::string* progress_note)> done;
  // When set, items that still failed after the last attempt stop the job on every rank:
  // "<failure_what> failed for N episode(s) (...); rerun the same command to resume".
  std::string failure_what;
};

struct JobResult {
  std::vector<int> todo;  // what this call had left to run (rank 0's scan)
  PoolReport pool;        // what still failed, the whole job's, with each item's own message
  long units = 0;         // the done() counts, summed over every rank
  int run_now = 0;        // items finished by this call, over every rank
  double seconds = 0;
};

// Runs the sequence above. `summarize` runs on rank 0 alone (not at all in a job that failed),
// with the folder still locked; it writes the summary, the folder's commit. Every rank returns
// the job's result.
JobResult run_job(const JobSpec& spec, const std::function<void(const JobResult&)>& summarize);

}  // namespace cd
