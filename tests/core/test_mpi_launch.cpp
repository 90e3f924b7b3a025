// How a command knows its launcher (core/mpi: detect_launch), from each launcher's variables:
// mpirun (OpenMPI), PMI-1/2 (srun --mpi=pmi2, MPICH's mpiexec), PMIx (srun --mpi=pmix, which sets
// no size variable), srun without an MPI plugin, and an sbatch script run without srun, which
// is one process whatever its allocation.
#include "core/mpi.hpp"

#include <map>
#include <string>

#include <gtest/gtest.h>

namespace cd {
namespace {

Launch launch_of(const std::map<std::string, std::string>& vars) {
  return detect_launch([&](const char* name) -> const char* {
    auto it = vars.find(name);
    return it == vars.end() ? nullptr : it->second.c_str();
  });
}

TEST(MpiLaunch, NoLauncherIsOneProcess) {
  const Launch l = launch_of({{"HOME", "/root"}});
  EXPECT_EQ(l.launcher, "");
  EXPECT_EQ(l.size, 1);
}

TEST(MpiLaunch, OpenMpisMpirun) {
  const Launch l = launch_of({{"OMPI_COMM_WORLD_SIZE", "4"}, {"OMPI_COMM_WORLD_RANK", "2"},
                              {"PMIX_RANK", "2"}, {"PMIX_NAMESPACE", "prterun-x"}});
  EXPECT_EQ(l.launcher, "mpirun");
  EXPECT_EQ(l.size, 4);
}

TEST(MpiLaunch, PmiTwoFromSrunOrMpiexec) {
  const Launch l = launch_of({{"PMI_SIZE", "8"}, {"PMI_RANK", "3"}, {"PMI_FD", "5"}});
  EXPECT_NE(l.launcher.find("PMI"), std::string::npos) << l.launcher;
  EXPECT_EQ(l.size, 8);
}

TEST(MpiLaunch, PmixUnderSrunTakesTheStepsTaskCount) {
  const Launch l = launch_of({{"PMIX_RANK", "0"}, {"PMIX_NAMESPACE", "slurm.pmix.77.0"},
                              {"SLURM_STEP_NUM_TASKS", "16"}, {"SLURM_PROCID", "0"},
                              {"SLURM_NTASKS", "16"}});
  EXPECT_NE(l.launcher.find("PMIx"), std::string::npos) << l.launcher;
  EXPECT_EQ(l.size, 16);
}

TEST(MpiLaunch, PmixAloneIsLaunchedWithTheSizeLeftToMpi) {
  const Launch l = launch_of({{"PMIX_NAMESPACE", "prterun-host-1234@1"}});
  EXPECT_NE(l.launcher.find("PMIx"), std::string::npos) << l.launcher;
  EXPECT_EQ(l.size, 0) << "launched, size unknown until MPI starts";
}

TEST(MpiLaunch, SrunWithoutAnMpiPluginIsStillSeen) {
  const Launch l = launch_of({{"SLURM_STEP_NUM_TASKS", "4"}, {"SLURM_PROCID", "1"},
                              {"SLURM_NTASKS", "4"}, {"SLURM_JOB_ID", "77"}});
  EXPECT_EQ(l.launcher, "srun");
  EXPECT_EQ(l.size, 4);
}

TEST(MpiLaunch, AnSbatchScriptWithoutSrunIsOneProcess) {
  // The batch script sees its allocation's task count, but no step of its own.
  const Launch l = launch_of({{"SLURM_NTASKS", "32"}, {"SLURM_JOB_ID", "77"},
                              {"SLURM_PROCID", "0"}});
  EXPECT_EQ(l.launcher, "");
  EXPECT_EQ(l.size, 1);
}

TEST(MpiLaunch, ASingleTaskSrunStepIsOneProcess) {
  const Launch l = launch_of({{"SLURM_STEP_NUM_TASKS", "1"}, {"SLURM_PROCID", "0"}});
  EXPECT_EQ(l.size, 1);
}

}  // namespace
}  // namespace cd
