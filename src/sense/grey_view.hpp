#pragma once
// The grey view the cim family's VAE sees: some BEV channels merged into one 64x64 plane.
#include <cstdint>
#include <string>
#include <vector>

namespace cd {

// The VAE's input: the BEV channels named by vae.view ("a+b": OR-ed into one plane), resized
// to 64x64 by area averaging when the BEV has another size (pixel values in [0, 1]).
struct GreyView {
  std::vector<int> channels;  // indices into the BEV channels
  uint8_t mask = 0;           // bit c set for each channel c (packed frames)
  int channel_count = 0, height = 0, width = 0;  // the BEV frame
  // Source rectangle of each output row / column: [y0[i], y1[i]) and [x0[j], x1[j]).
  std::vector<int> y0, y1, x0, x1;
};

// Throws ConfigError naming the unknown channel and the known ones.
GreyView resolve_view(const std::string& view, const std::vector<std::string>& channel_names,
                     int height, int width);
// One 64x64 plane from a packed frame (H*W bytes, bit c = channel c) ...
void view_from_packed(const GreyView& v, const uint8_t* packed, float* out);
// ... or from C planes of H*W bytes, 0/255 (what agents are given).
void view_from_planes(const GreyView& v, const uint8_t* planes, float* out);

}  // namespace cd
