// The copycat probe's scene shift (diagnostics/probe): a moving history shifts the scene up.
#include "diagnostics/probe.hpp"

#include <gtest/gtest.h>

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

}  // namespace
}  // namespace cd
