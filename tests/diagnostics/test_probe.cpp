// The copycat probe's moving history (diagnostics/probe): the BEV's shifts the scene up; the
// camera's is drawn from a pose behind the ego (the replay itself: tests/e2e/test_camera_cli).
#include "diagnostics/probe.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

namespace cd {
namespace {

TEST(Probe, MovingHistoryShiftsTheSceneUp) {
  // 1 channel, 4 rows of 2 pixels: rows hold 1, 2, 3, 4.
  const unsigned char cur[8] = {1, 1, 2, 2, 3, 3, 4, 4};
  unsigned char out[8];
  shift_frame_up(cur, 1, 4, 2, 1, out);
  EXPECT_EQ(std::vector<unsigned char>(out, out + 8),
            (std::vector<unsigned char>{2, 2, 3, 3, 4, 4, 0, 0}));
  shift_frame_up(cur, 1, 4, 2, 0, out);
  EXPECT_EQ(std::vector<unsigned char>(out, out + 8), std::vector<unsigned char>(cur, cur + 8));
  shift_frame_up(cur, 1, 4, 2, 9, out);
  EXPECT_EQ(std::vector<unsigned char>(out, out + 8), std::vector<unsigned char>(8, 0));
}

TEST(Probe, TheCamerasMovingHistoryStandsBehindTheEgoOnItsHeading) {
  // Heading north (pi/2): 3 m behind (1, 2) is (1, -1); east (0): 2 m behind (5, 0) is (3, 0).
  const Pose2 north = pose_behind(Pose2{{1.0, 2.0}, std::acos(0.0)}, 3.0);
  EXPECT_NEAR(north.pos.x, 1.0, 1e-12);
  EXPECT_NEAR(north.pos.y, -1.0, 1e-12);
  EXPECT_DOUBLE_EQ(north.heading, std::acos(0.0));
  const Pose2 east = pose_behind(Pose2{{5.0, 0.0}, 0.0}, 2.0);
  EXPECT_DOUBLE_EQ(east.pos.x, 3.0);
  EXPECT_DOUBLE_EQ(east.pos.y, 0.0);
}

}  // namespace
}  // namespace cd
