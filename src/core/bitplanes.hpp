#pragma once
// Binary image channels packed as bits of one byte per pixel (bit c = channel c), and their
// expansion into planes of 0/255 bytes. A packed frame is 8x smaller than its planes, which
// makes recording long episodes cheap; files and agents get the planes.
#include <cstddef>
#include <cstdint>

namespace cd {

inline constexpr int kMaxPackedChannels = 8;

// out: channels planes of `pixels` bytes each.
inline void unpack_planes(const uint8_t* packed, size_t pixels, int channels, uint8_t* out) {
  for (int c = 0; c < channels; ++c) {
    uint8_t* plane = out + static_cast<size_t>(c) * pixels;
    for (size_t i = 0; i < pixels; ++i) plane[i] = uint8_t(-((packed[i] >> c) & 1));
  }
}

// The inverse: `channels` planes of `pixels` bytes (non-zero = on) into one byte per pixel.
inline void pack_planes(const uint8_t* planes, size_t pixels, int channels, uint8_t* out) {
  for (size_t i = 0; i < pixels; ++i) out[i] = 0;
  for (int c = 0; c < channels; ++c) {
    const uint8_t* plane = planes + static_cast<size_t>(c) * pixels;
    for (size_t i = 0; i < pixels; ++i)
      if (plane[i]) out[i] = static_cast<uint8_t>(out[i] | (1u << c));
  }
}

}  // namespace cd
