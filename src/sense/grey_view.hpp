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

// Throws ConfigError naming the unknown channel and the known ones (`key`: the setting).
GreyView resolve_view(const std::string& view, const std::vector<std::string>& channel_names,
                     int height, int width, const std::string& key = "vae.view");

// The channels of a multi-channel input that `view` ("a+b", the names of resolve_view) keeps:
// one flag per channel name, all set for an empty view. Throws like resolve_view.
std::vector<bool> view_channel_flags(const std::string& view,
                                     const std::vector<std::string>& channel_names,
                                     const std::string& key);
// Sets every plane of a C x pixels frame whose flag is off to 0.
void blank_other_channels(const std::vector<bool>& keep, size_t pixels, float* frame);
// One 64x64 plane from a packed frame (H*W bytes, bit c = channel c) ...
void view_from_packed(const GreyView& v, const uint8_t* packed, float* out);
// ... or from C planes of H*W bytes, 0/255 (what agents are given).
void view_from_planes(const GreyView& v, const uint8_t* planes, float* out);

}  // namespace cd
