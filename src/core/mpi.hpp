#pragma once
// Jobs spread over MPI ranks (SPEC section 12). OpenMPI is optional: built without it
// (CD_HAVE_MPI undefined) every call here is the single-process answer, and a command started
// under mpirun with more than one rank is refused in one line.
//
// Under `mpirun -np N causaldrive collect|eval ...` every rank runs the same command. The
// episodes are split in the worker pool (core/worker_pool.cpp): rank 0's list of what is still
// to do is broadcast, each rank runs every N-th of it in one world, and the failures are
// gathered to every rank. Rank 0 alone removes stale temporaries, holds the run folder's lock
// and writes the summary; the other ranks share its lock and print nothing.
#include <functional>
#include <string>
#include <vector>

#include "core/error.hpp"

namespace cd {

// The error another rank raised and reported, repeated on this rank to stop it too (the CLI
// prints nothing more for it).
struct MpiEchoError : Error {
  using Error::Error;
};

// This process's place in its MPI job: {0, 1} when not started by mpirun.
struct MpiPlace {
  int rank = 0;
  int size = 1;
};

// The launcher that started this process, from its environment variables: "mpirun" (OpenMPI),
// PMI-1/2 (srun --mpi=pmi2, MPICH's mpiexec), PMIx (srun --mpi=pmix, prterun), "srun" (tasks
// without an MPI plugin), or "" when none did (an sbatch script without srun is one process).
// `size` is the task count it names: 1 when not launched, 0 when launched but the size is MPI's
// to tell (PMIx outside srun).
struct Launch {
  std::string launcher;
  int size = 1;
};
Launch detect_launch(const std::function<const char*(const char*)>& env);

// Starts MPI when a launcher started the process (and the build has MPI), for the life of the
// object; main() holds one. Throws ConfigError when a launcher started several tasks of a build
// without MPI, or more tasks than MPI sees ranks (srun with no MPI plugin this MPI can use).
class MpiSession {
 public:
  MpiSession(int* argc, char*** argv);
  ~MpiSession();
  MpiSession(const MpiSession&) = delete;
  MpiSession& operator=(const MpiSession&) = delete;
};

// An error every rank of the job raises at once (after a collective, on the same gathered
// facts): rank 0 reports it, the other ranks stop without repeating it.
[[noreturn]] void throw_job_error(const std::string& what);

// Runs `step` on rank 0 alone (the lock, the folder's claim): its error stops every rank, rank 0
// rethrowing it and the others raising MpiEchoError. Outside an MPI job: just runs it.
void mpi_lead_step(const std::function<void()>& step);

// Whether the error being raised is known to every rank (throw_job_error, mpi_lead_step): the
// ranks then end on their own, and no rank needs MPI_Abort.
bool mpi_error_shared();

// Whether this build was compiled with MPI.
bool mpi_compiled();
const MpiPlace& mpi_place();
inline bool mpi_lead() { return mpi_place().rank == 0; }
inline bool mpi_distributed() { return mpi_place().size > 1; }

// "rank R of N on HOST"
std::string mpi_where();

// Collective over every rank (no-ops in one process, and in a worker forked from a rank):
void mpi_barrier();
// rank 0's `values`, on every rank.
std::vector<int> mpi_broadcast(const std::vector<int>& values);
// rank 0's text, on every rank.
std::string mpi_broadcast(const std::string& text);
// The sum of every rank's `value`.
long mpi_sum(long value);
// Every rank's `values`, concatenated in rank order.
std::vector<int> mpi_all_gather(const std::vector<int>& values);
// Every rank's text, in rank order.
std::vector<std::string> mpi_all_gather(const std::string& text);

// Ends every rank of the job (after an error this rank cannot recover from: the others may be
// waiting in a collective). Returns only when not distributed.
void mpi_abort(int code);

}  // namespace cd
