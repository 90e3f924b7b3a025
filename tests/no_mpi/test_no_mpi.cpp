// core/mpi as a build without OpenMPI compiles it (CD_HAVE_MPI undefined, whatever this build
// found): one process, collectives that return their input, and a command started by mpirun
// on several ranks refused in one line. Its own executable: the library's mpi.cpp is the MPI
// one when OpenMPI is installed.
#undef CD_HAVE_MPI
#include "../../src/core/mpi.cpp"

#include <gtest/gtest.h>
#include <stdlib.h>

namespace cd {
namespace {

TEST(NoMpiBuild, RunsAsOneProcessAndRefusesSeveralRanks) {
  EXPECT_FALSE(mpi_compiled());
  ::unsetenv("OMPI_COMM_WORLD_SIZE");
  for (const char* var : {"PMIX_SIZE", "PMI_SIZE", "PMIX_RANK", "PMIX_NAMESPACE",
                          "SLURM_STEP_NUM_TASKS", "SLURM_PROCID"})
    ::unsetenv(var);
  {
    int argc = 1;
    char name[] = "causaldrive";
    char* args[] = {name, nullptr};
    char** argv = args;
    MpiSession session(&argc, &argv);  // not under mpirun: nothing to refuse
    EXPECT_TRUE(mpi_lead());
    EXPECT_FALSE(mpi_distributed());
    EXPECT_EQ(mpi_broadcast(std::vector<int>{3, 1, 2}), (std::vector<int>{3, 1, 2}));
    EXPECT_EQ(mpi_all_gather(std::vector<int>{4, 5}), (std::vector<int>{4, 5}));
    EXPECT_EQ(mpi_all_gather(std::string("x")), (std::vector<std::string>{"x"}));
    EXPECT_EQ(mpi_sum(7), 7);
    EXPECT_THROW(throw_job_error("stop"), Error);
  }
  ::setenv("OMPI_COMM_WORLD_SIZE", "3", 1);
  int argc = 1;
  char name[] = "causaldrive";
  char* args[] = {name, nullptr};
  char** argv = args;
  try {
    MpiSession session(&argc, &argv);
    ADD_FAILURE() << "three ranks of a build without MPI were not refused";
  } catch (const ConfigError& e) {
    EXPECT_STREQ(e.what(), "started by mpirun with 3 tasks, but this build has no MPI (install "
                           "libopenmpi-dev and rebuild)");
  }
  ::unsetenv("OMPI_COMM_WORLD_SIZE");
  // srun --mpi=pmix sets no size variable: the step's task count says it.
  ::setenv("PMIX_RANK", "0", 1);
  ::setenv("SLURM_STEP_NUM_TASKS", "4", 1);
  ::setenv("SLURM_PROCID", "0", 1);
  try {
    MpiSession session(&argc, &argv);
    ADD_FAILURE() << "four srun tasks of a build without MPI were not refused";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("with 4 tasks, but this build has no MPI"),
              std::string::npos)
        << e.what();
  }
  ::unsetenv("PMIX_RANK");
  ::unsetenv("SLURM_STEP_NUM_TASKS");
  ::unsetenv("SLURM_PROCID");
}

}  // namespace
}  // namespace cd
