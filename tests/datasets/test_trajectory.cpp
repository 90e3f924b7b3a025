// The samples of dim / rip (datasets/trajectory): past and future positions in the ego frame,
// clamped at the start of an episode.
#include "datasets/trajectory.hpp"

#include <gtest/gtest.h>

#include "../support/dim_toy_data.hpp"
#include "datasets/episode_set.hpp"

namespace cd {
namespace {

using test::TempDir;

TEST(DimSamples, PositionsAreInTheEgoFrameAndClampedAtTheStart) {
  TempDir dir("cd-dim");
  test::write_toy_folder(dir / "data", 3);
  EpisodeSet set = load_episode_set(dir / "data");
  DimSettings d;  // horizon 4, step 5, past 4
  float past[8], future[8];
  dim_sample_positions(set.episodes[2], 7, d, past, future);  // 4 m/s, heading 0.8
  for (int k = 0; k < 4; ++k) {
    EXPECT_NEAR(future[2 * k], 4.0 * 0.5 * (k + 1), 1e-4);  // straight ahead
    EXPECT_NEAR(future[2 * k + 1], 0.0, 1e-4);
  }
  EXPECT_NEAR(past[0], -2.0, 1e-4);  // t = 2
  EXPECT_NEAR(past[2], -2.8, 1e-4);  // t = -3 -> 0
  EXPECT_NEAR(past[6], -2.8, 1e-4);
  EXPECT_NEAR(past[7], 0.0, 1e-4);
}

}  // namespace
}  // namespace cd
