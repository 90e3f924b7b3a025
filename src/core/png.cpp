#include "core/png.hpp"

#define STB_IMAGE_WRITE_IMPLEMENTATION
#define STB_IMAGE_WRITE_STATIC  // keeps stb's symbols private to this file (bev.cpp has its own)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmissing-field-initializers"
#pragma GCC diagnostic ignored "-Wunused-function"
#include <stb/stb_image_write.h>
#pragma GCC diagnostic pop

#include "core/atomic_file.hpp"
#include "core/error.hpp"

namespace cd {

namespace {
void append(void* ctx, void* data, int size) {
  static_cast<std::string*>(ctx)->append(static_cast<const char*>(data), static_cast<size_t>(size));
}
}  // namespace

std::string encode_png(const std::vector<uint8_t>& pixels, int width, int height, int components) {
  if (width <= 0 || height <= 0 || (components != 1 && components != 3) ||
      pixels.size() != static_cast<size_t>(width) * height * components)
    throw IoError("encode_png: " + std::to_string(pixels.size()) + " bytes do not make a " +
                  std::to_string(width) + "x" + std::to_string(height) + "x" +
                  std::to_string(components) + " image");
  std::string png;
  if (!stbi_write_png_to_func(append, &png, width, height, components, pixels.data(),
                              width * components))
    throw IoError("encode_png: PNG encoding failed");
  return png;
}

void write_png_gray(const std::string& path, const std::vector<uint8_t>& pixels, int width,
                    int height) {
  write_file_atomic(path, encode_png(pixels, width, height, 1));
}

void write_png_rgb(const std::string& path, const std::vector<uint8_t>& pixels, int width,
                   int height) {
  write_file_atomic(path, encode_png(pixels, width, height, 3));
}

void append_rgb_rows(const uint8_t* planes, int height, int width, std::vector<uint8_t>& rgb) {
  const size_t plane = static_cast<size_t>(height) * width, at = rgb.size();
  rgb.resize(at + plane * 3);
  for (size_t p = 0; p < plane; ++p)
    for (size_t c = 0; c < 3; ++c) rgb[at + p * 3 + c] = planes[c * plane + p];
}

}  // namespace cd
