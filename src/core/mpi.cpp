#include "core/mpi.hpp"

#include <unistd.h>

#include <algorithm>
#include <cstdlib>

#include "core/error.hpp"
#include "core/process.hpp"

#ifdef CD_HAVE_MPI
#define OMPI_SKIP_MPICXX 1  // the C API only: no C++ bindings to link
#define MPICH_SKIP_MPICXX 1
#include <mpi.h>
#endif

namespace cd {

namespace {

MpiPlace place;
bool started = false;
pid_t mpi_pid = 0;  // the process that started MPI: a forked worker never takes part

bool in_job() { return place.size > 1 && getpid() == mpi_pid; }

bool error_shared = false;  // this rank's error is known to every rank (no abort needed)

}  // namespace

Launch detect_launch(const std::function<const char*(const char*)>& env) {
  auto number = [&](const char* var) {
    const char* v = env(var);
    return v == nullptr ? -1 : std::max(0, std::atoi(v));
  };
  const int slurm_tasks = number("SLURM_STEP_NUM_TASKS");  // set by srun for its tasks only
  if (const int n = number("OMPI_COMM_WORLD_SIZE"); n >= 0) return {"mpirun", std::max(1, n)};
  if (const int n = number("PMI_SIZE"); n >= 0)
    return {"PMI (srun --mpi=pmi2, mpiexec)", std::max(1, n)};
  // PMIx names the job and the rank, not its size; under srun the step's task count does.
  if (env("PMIX_RANK") != nullptr || env("PMIX_NAMESPACE") != nullptr)
    return {"PMIx (srun --mpi=pmix, prterun)", slurm_tasks > 0 ? slurm_tasks : 0};
  // srun with no MPI plugin: tasks with no way to reach each other.
  if (slurm_tasks > 1 && env("SLURM_PROCID") != nullptr) return {"srun", slurm_tasks};
  return {"", 1};
}

bool mpi_compiled() {
#ifdef CD_HAVE_MPI
  return true;
#else
  return false;
#endif
}

MpiSession::MpiSession(int* argc, char*** argv) {
  const Launch launch = detect_launch([](const char* var) { return std::getenv(var); });
  const std::string tasks = launch.size > 0 ? std::to_string(launch.size) + " tasks" : "tasks";
#ifdef CD_HAVE_MPI
  if (!launch.launcher.empty()) {
    MPI_Init(argc, argv);
    MPI_Comm_rank(MPI_COMM_WORLD, &place.rank);
    MPI_Comm_size(MPI_COMM_WORLD, &place.size);
    mpi_pid = getpid();
    started = true;
    if (launch.size > 1 && place.size != launch.size)
      throw ConfigError(launch.launcher + " started " + tasks + ", but MPI sees " +
                        std::to_string(place.size) +
                        " rank(s): each would run the whole job; launch with srun --mpi=pmix "
                        "(or pmi2; srun --mpi=list shows them) or mpirun");
  }
#else
  (void)argc;
  (void)argv;
  if (launch.size > 1)
    throw ConfigError("started by " + launch.launcher + " with " + tasks +
                      ", but this build has no MPI (install libopenmpi-dev and rebuild)");
#endif
}

MpiSession::~MpiSession() {
#ifdef CD_HAVE_MPI
  if (started && getpid() == mpi_pid) MPI_Finalize();
#endif
}

const MpiPlace& mpi_place() { return place; }

std::string mpi_where() {
  return "rank " + std::to_string(place.rank) + " of " + std::to_string(place.size) + " on " +
         host_name();
}

std::vector<int> mpi_broadcast(const std::vector<int>& values) {
#ifdef CD_HAVE_MPI
  if (in_job()) {
    int n = static_cast<int>(values.size());
    MPI_Bcast(&n, 1, MPI_INT, 0, MPI_COMM_WORLD);
    std::vector<int> out = place.rank == 0 ? values : std::vector<int>(n);
    MPI_Bcast(out.data(), n, MPI_INT, 0, MPI_COMM_WORLD);
    return out;
  }
#endif
  return values;
}

std::string mpi_broadcast(const std::string& text) {
#ifdef CD_HAVE_MPI
  if (in_job()) {
    std::vector<int> chars(text.begin(), text.end());
    std::vector<int> out = mpi_broadcast(chars);
    return std::string(out.begin(), out.end());
  }
#endif
  return text;
}

long mpi_sum(long value) {
#ifdef CD_HAVE_MPI
  if (in_job()) {
    long total = 0;
    MPI_Allreduce(&value, &total, 1, MPI_LONG, MPI_SUM, MPI_COMM_WORLD);
    return total;
  }
#endif
  return value;
}

std::vector<int> mpi_all_gather(const std::vector<int>& values) {
#ifdef CD_HAVE_MPI
  if (in_job()) {
    int n = static_cast<int>(values.size());
    std::vector<int> counts(place.size), offsets(place.size, 0);
    MPI_Allgather(&n, 1, MPI_INT, counts.data(), 1, MPI_INT, MPI_COMM_WORLD);
    int total = 0;
    for (int r = 0; r < place.size; ++r) {
      offsets[r] = total;
      total += counts[r];
    }
    std::vector<int> out(total);
    MPI_Allgatherv(values.data(), n, MPI_INT, out.data(), counts.data(), offsets.data(), MPI_INT,
                   MPI_COMM_WORLD);
    return out;
  }
#endif
  return values;
}

std::vector<std::string> mpi_all_gather(const std::string& text) {
#ifdef CD_HAVE_MPI
  if (in_job()) {
    // Each rank's text, terminated by -1 (a char is never -1 as an unsigned byte).
    std::vector<int> mine;
    for (unsigned char c : text) mine.push_back(c);
    mine.push_back(-1);
    std::vector<std::string> out(1);
    for (int c : mpi_all_gather(mine)) {
      if (c < 0) out.emplace_back();
      else out.back().push_back(static_cast<char>(c));
    }
    out.pop_back();
    return out;
  }
#endif
  return {text};
}

void throw_job_error(const std::string& what) {
  error_shared = in_job();
  if (place.rank == 0) throw Error(what);
  throw MpiEchoError(what);
}

bool mpi_error_shared() { return error_shared; }

void mpi_lead_step(const std::function<void()>& step) {
  if (!in_job()) {
    step();
    return;
  }
  if (place.rank == 0) {
    try {
      step();
    } catch (const std::exception& e) {
      mpi_broadcast(std::string(e.what()).empty() ? std::string("error") : std::string(e.what()));
      error_shared = true;  // the others stop too: no abort
      throw;
    }
  }
  const std::string error = mpi_broadcast(std::string());
  if (!error.empty()) {
    error_shared = true;
    throw MpiEchoError(error);
  }
}

void mpi_barrier() {
#ifdef CD_HAVE_MPI
  if (in_job()) MPI_Barrier(MPI_COMM_WORLD);
#endif
}

void mpi_abort(int code) {
#ifdef CD_HAVE_MPI
  if (in_job()) MPI_Abort(MPI_COMM_WORLD, code);
#else
  (void)code;
#endif
}

}  // namespace cd
