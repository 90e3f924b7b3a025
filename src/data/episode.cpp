#include "data/episode.hpp"

#include <cstring>

namespace cd {

void EpisodeData::frame_planes(size_t t, uint8_t* out) const {
  if (!rgb.empty())
    std::memcpy(out, rgb.data() + t * frame_bytes(), frame_bytes());
  else if (!bev_packed.empty())
    unpack_planes(bev_packed.data() + t * frame_pixels(), frame_pixels(), channels, out);
  else
    std::memcpy(out, bev.data() + t * frame_bytes(), frame_bytes());
}

}  // namespace cd
