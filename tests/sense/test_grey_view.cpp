// The grey view of the cim family's VAE (sense/grey_view): channels ORed, areas averaged.
#include "sense/grey_view.hpp"

#include <gtest/gtest.h>

#include <cstdint>
#include <string>
#include <vector>

#include "core/error.hpp"

namespace cd {
namespace {

TEST(GreyView, OrsChannelsAndAveragesAreas) {
  const std::vector<std::string> names = {"drivable", "markings", "route", "vehicles", "pedestrians"};
  GreyView v = resolve_view("vehicles+pedestrians", names, 128, 128);
  EXPECT_EQ(v.channels, (std::vector<int>{3, 4}));
  EXPECT_EQ(v.mask, (1 << 3) | (1 << 4));
  std::vector<uint8_t> packed(128 * 128, 0);
  packed[0] = 1 << 3;                       // cell (0,0): 1 of 4 pixels
  packed[2] = 1 << 4, packed[3] = 1 << 4;   // cell (0,1): 2 of 4 (another channel)
  packed[128 + 2] = 1 << 3, packed[128 + 3] = 1 << 0;  // cell (0,1): +1 (drivable is not viewed)
  std::vector<float> out(64 * 64);
  view_from_packed(v, packed.data(), out.data());
  EXPECT_FLOAT_EQ(out[0], 0.25f);
  EXPECT_FLOAT_EQ(out[1], 0.75f);
  EXPECT_FLOAT_EQ(out[2], 0.0f);
  // The same frame as 0/255 planes gives the same view.
  std::vector<uint8_t> planes(5 * 128 * 128, 0);
  for (size_t i = 0; i < packed.size(); ++i)
    for (int c = 0; c < 5; ++c)
      if (packed[i] >> c & 1) planes[c * 128 * 128 + i] = 255;
  std::vector<float> out2(64 * 64);
  view_from_planes(v, planes.data(), out2.data());
  EXPECT_EQ(out, out2);
  // 64x64 is taken as it is.
  GreyView same = resolve_view("vehicles", names, 64, 64);
  std::vector<uint8_t> p64(64 * 64, 0);
  p64[65] = 1 << 3;
  view_from_packed(same, p64.data(), out.data());
  EXPECT_FLOAT_EQ(out[65], 1.0f);
  EXPECT_FLOAT_EQ(out[64], 0.0f);
  try {
    resolve_view("vehicles+cars", names, 64, 64);
    FAIL() << "no error";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("'cars'"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace cd
