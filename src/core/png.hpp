#pragma once
// Small PNG writer (stb_image_write) for the figures of a run: 8-bit grey or RGB pixels, row
// major, written atomically (core/atomic_file.hpp).
#include <cstdint>
#include <string>
#include <vector>

namespace cd {

// The PNG bytes of a width x height image with `components` (1 grey, 3 RGB) bytes per pixel.
// Throws IoError when encoding fails or the buffer has the wrong size.
std::string encode_png(const std::vector<uint8_t>& pixels, int width, int height, int components);

void write_png_gray(const std::string& path, const std::vector<uint8_t>& pixels, int width,
                    int height);
void write_png_rgb(const std::string& path, const std::vector<uint8_t>& pixels, int width,
                   int height);
// Appends an RGB frame stored as 3 planes of height x width bytes (the camera's and MuJoCo's
// frames) to `rgb` as interleaved rows, below what it holds.
void append_rgb_rows(const uint8_t* planes, int height, int width, std::vector<uint8_t>& rgb);

}  // namespace cd
