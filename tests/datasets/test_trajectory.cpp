// The samples of dim / rip (datasets/trajectory): past and future positions in the ego frame,
// clamped at the start of an episode.
#include "datasets/trajectory.hpp"

#include <gtest/gtest.h>

#include <cmath>

#include "../support/dim_toy_data.hpp"
#include "data/h5_episode.hpp"
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

// An augmented frame (collect.augment) was rendered from the true pose shifted 1 m to the left
// and turned 0.1 rad: its positions are in that pose's frame, so the expert's straight path
// ahead is seen 1 m to the right and turned 0.1 rad clockwise. Frames without a shift keep the
// true frame. The shift and turn travel from the file through load_episode_set.
TEST(DimSamples, AnAugmentedFrameSeesThePathFromItsShiftedPose) {
  TempDir dir("cd-dim");
  test::write_toy_folder(dir / "data", 3);
  const std::string file = dir / ("data/" + test::fake_episode_name(2));
  EpisodeMeta meta;
  EpisodeData d = read_episode(file, &meta);
  d.augment.assign(2 * d.frames(), 0.0f);
  d.augment[2 * 7] = 1.0f;
  d.augment[2 * 7 + 1] = 0.1f;
  write_episode(file, meta, d);
  EpisodeSet set = load_episode_set(dir / "data");
  ASSERT_EQ(set.episodes[2].augment.size(), 2 * d.frames());
  DimSettings dim;
  float past[8], future[8];
  dim_sample_positions(set.episodes[2], 7, dim, past, future);  // 4 m/s, straight
  for (int k = 0; k < 4; ++k) {
    // (x, 0) of the true frame is (x, -1) from the shifted origin, then turned by -0.1 rad.
    const double x = 2.0 * (k + 1);
    EXPECT_NEAR(future[2 * k], x * std::cos(0.1) - std::sin(0.1), 1e-4) << k;
    EXPECT_NEAR(future[2 * k + 1], -x * std::sin(0.1) - std::cos(0.1), 1e-4) << k;
  }
  EXPECT_NEAR(past[0], -2.0 * std::cos(0.1) - std::sin(0.1), 1e-4);  // t = 2
  EXPECT_NEAR(past[1], 2.0 * std::sin(0.1) - std::cos(0.1), 1e-4);
  dim_sample_positions(set.episodes[2], 8, dim, past, future);  // a true frame
  EXPECT_NEAR(future[0], 2.0, 1e-4);
  EXPECT_NEAR(future[1], 0.0, 1e-4);
}

}  // namespace
}  // namespace cd
