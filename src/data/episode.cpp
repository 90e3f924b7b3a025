#include "data/episode.hpp"

#include <cstring>

#include <zlib.h>

#include "core/error.hpp"

namespace cd {

void inflate_frame(const uint8_t* in, size_t n, uint8_t* out, size_t out_bytes,
                   const std::string& what) {
  uLongf got = static_cast<uLongf>(out_bytes);
  if (uncompress(out, &got, in, static_cast<uLong>(n)) != Z_OK || got != out_bytes)
    throw DataError(what + ": a stored frame does not inflate to " + std::to_string(out_bytes) +
                    " bytes (the file is damaged)");
}

void EpisodeData::frame_planes(size_t t, uint8_t* out) const {
  if (!rgb_offsets.empty())
    inflate_frame(rgb_deflated.data() + rgb_offsets[t], rgb_offsets[t + 1] - rgb_offsets[t], out,
                  frame_bytes(), "camera frame " + std::to_string(t));
  else if (!rgb.empty())
    std::memcpy(out, rgb.data() + t * frame_bytes(), frame_bytes());
  else if (!bev_packed.empty())
    unpack_planes(bev_packed.data() + t * frame_pixels(), frame_pixels(), channels, out);
  else
    std::memcpy(out, bev.data() + t * frame_bytes(), frame_bytes());
}

}  // namespace cd
