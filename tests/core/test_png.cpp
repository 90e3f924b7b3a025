// The PNG writer (core/png): the header carries the size and colour type; a wrong size throws.
#include "core/png.hpp"

#include <gtest/gtest.h>

#include <cstdint>
#include <string>
#include <vector>

#include "../support/test_support.hpp"
#include "core/error.hpp"

namespace cd {
namespace {

TEST(Png, HeaderHasTheSize) {
  test::TempDir dir("cdtest-png");
  std::vector<uint8_t> rgb(7 * 5 * 3, 200);
  write_png_rgb(dir / "a.png", rgb, 7, 5);
  const std::string bytes = test::read_text(dir / "a.png");
  ASSERT_GT(bytes.size(), 24u);
  EXPECT_EQ(bytes.substr(1, 3), "PNG");
  auto be32 = [&](size_t o) {
    return (uint32_t(uint8_t(bytes[o])) << 24) | (uint32_t(uint8_t(bytes[o + 1])) << 16) |
           (uint32_t(uint8_t(bytes[o + 2])) << 8) | uint32_t(uint8_t(bytes[o + 3]));
  };
  EXPECT_EQ(be32(16), 7u);
  EXPECT_EQ(be32(20), 5u);
  EXPECT_EQ(uint8_t(bytes[25]), 2);  // colour type RGB
  EXPECT_THROW(write_png_gray(dir / "b.png", rgb, 7, 5), IoError);  // wrong size
}

}  // namespace
}  // namespace cd
