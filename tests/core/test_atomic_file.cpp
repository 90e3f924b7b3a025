// Temporary names of atomic writes (core/atomic_file): host, MPI rank and pid, so that writers
// on two nodes whose containers reuse a pid never share one; stale ones are removed by name.
#include "core/atomic_file.hpp"

#include <unistd.h>

#include <filesystem>
#include <string>

#include <gtest/gtest.h>

#include "../support/test_support.hpp"
#include "core/process.hpp"

namespace cd {
namespace {

TEST(AtomicFile, TemporariesAreNamedByHostRankAndPid) {
  const std::string pid = std::to_string(::getpid());
  ::setenv("CAUSALDRIVE_HOST", "node-a", 1);
  const std::string a = temp_path_for("/runs/x/episode_000003.h5");
  ::setenv("CAUSALDRIVE_HOST", "node-b", 1);
  const std::string b = temp_path_for("/runs/x/episode_000003.h5");
  ::setenv("CAUSALDRIVE_HOST", "odd/name here", 1);
  const std::string odd = temp_path_for("/runs/x/episode_000003.h5");
  ::unsetenv("CAUSALDRIVE_HOST");
  EXPECT_EQ(a, "/runs/x/episode_000003.h5.node-a.0." + pid + ".tmp");
  EXPECT_EQ(b, "/runs/x/episode_000003.h5.node-b.0." + pid + ".tmp");
  EXPECT_NE(a, b) << "the same pid on two hosts";
  EXPECT_EQ(odd, "/runs/x/episode_000003.h5.odd_name_here.0." + pid + ".tmp")
      << "a host name never adds a folder";
}

TEST(AtomicFile, AWriteLeavesNoTemporaryAndStaleOnesAreRemoved) {
  test::TempDir dir("cdtest-atomic");
  const std::string path = dir / "results.json";
  write_file_atomic(path, "{}\n");
  EXPECT_EQ(test::read_text(path), "{}\n");
  test::write_text(path + ".node-b.3.4242.tmp", "half");
  size_t entries = 0;
  for (const auto& e : std::filesystem::directory_iterator(dir.path())) {
    (void)e;
    ++entries;
  }
  EXPECT_EQ(entries, 2u);
  remove_stale_temporaries(dir.path());
  EXPECT_FALSE(std::filesystem::exists(path + ".node-b.3.4242.tmp"));
  EXPECT_EQ(test::read_text(path), "{}\n");
}

}  // namespace
}  // namespace cd
