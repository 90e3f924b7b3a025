#pragma once
// The BEV's colours for people (write_bev_png, attention maps): kept apart from sense/bev.hpp,
// which most of the code includes, so that pictures can change without rebuilding it.
#include <cstdint>
#include <vector>

namespace cd {

// A C x H x W frame (bytes, non-zero = on) composited in colour on a dark background, for
// people to look at, not for training: H*W RGB triplets, row major, one per pixel. Channels
// are drawn in order, each over the ones before (the route blended with what lies under it),
// so a pixel shows the highest channel that is on there. Throws Error for C outside [1, 8].
std::vector<uint8_t> bev_colour(const uint8_t* frame, int channels, int height, int width);

// A frame as people see it, H*W RGB triplets: an RGB frame's own colours (`rgb`: the front
// camera's, MuJoCo-Image's; 3 planes), else the BEV's colours above.
std::vector<uint8_t> frame_picture(const uint8_t* frame, int channels, int height, int width,
                                   bool rgb);

}  // namespace cd
