#include "sense/grey_view.hpp"

#include <algorithm>

#include "core/error.hpp"

namespace cd {

namespace {
constexpr int kOut = 64;  // the VAE's input size (nn/beta_vae.hpp kVaeSize)

// Area resampling: output cell i covers source [i*n/64, (i+1)*n/64), at least one pixel.
void ranges(int n, std::vector<int>& lo, std::vector<int>& hi) {
  lo.resize(kOut);
  hi.resize(kOut);
  for (int i = 0; i < kOut; ++i) {
    lo[i] = std::min(n - 1, i * n / kOut);
    hi[i] = std::max(lo[i] + 1, (i + 1) * n / kOut);
  }
}

template <class On>
void resample(const GreyView& v, On on, float* out) {
  if (v.height == kOut && v.width == kOut) {
    for (int i = 0; i < kOut * kOut; ++i) out[i] = on(static_cast<size_t>(i)) ? 1.0f : 0.0f;
    return;
  }
  for (int y = 0; y < kOut; ++y)
    for (int x = 0; x < kOut; ++x) {
      int count = 0, set = 0;
      for (int sy = v.y0[y]; sy < v.y1[y]; ++sy)
        for (int sx = v.x0[x]; sx < v.x1[x]; ++sx) {
          ++count;
          set += on(static_cast<size_t>(sy) * v.width + sx) ? 1 : 0;
        }
      out[y * kOut + x] = static_cast<float>(set) / static_cast<float>(count);
    }
}

std::string join(const std::vector<std::string>& names) {
  std::string s;
  for (const auto& n : names) s += (s.empty() ? "" : ", ") + n;
  return s;
}
}  // namespace

GreyView resolve_view(const std::string& view, const std::vector<std::string>& channel_names,
                     int height, int width, const std::string& key) {
  GreyView v;
  v.channel_count = static_cast<int>(channel_names.size());
  v.height = height;
  v.width = width;
  size_t start = 0;
  while (start <= view.size()) {
    size_t plus = view.find('+', start);
    std::string name = view.substr(start, plus == std::string::npos ? std::string::npos : plus - start);
    auto it = std::find(channel_names.begin(), channel_names.end(), name);
    if (name.empty() || it == channel_names.end())
      throw ConfigError(key + ": no BEV channel '" + name + "' in the data (channels: " +
                        join(channel_names) + ")");
    int c = static_cast<int>(it - channel_names.begin());
    if (c >= 8) throw ConfigError(key + ": channel '" + name + "' beyond the 8 packed channels");
    if (std::find(v.channels.begin(), v.channels.end(), c) == v.channels.end()) v.channels.push_back(c);
    v.mask |= static_cast<uint8_t>(1u << c);
    if (plus == std::string::npos) break;
    start = plus + 1;
  }
  ranges(height, v.y0, v.y1);
  ranges(width, v.x0, v.x1);
  return v;
}

void view_from_packed(const GreyView& v, const uint8_t* packed, float* out) {
  resample(v, [&](size_t i) { return (packed[i] & v.mask) != 0; }, out);
}

void view_from_planes(const GreyView& v, const uint8_t* planes, float* out) {
  const size_t pixels = static_cast<size_t>(v.height) * v.width;
  resample(v, [&](size_t i) {
    for (int c : v.channels)
      if (planes[static_cast<size_t>(c) * pixels + i]) return true;
    return false;
  }, out);
}

std::vector<bool> view_channel_flags(const std::string& view,
                                     const std::vector<std::string>& channel_names,
                                     const std::string& key) {
  std::vector<bool> keep(channel_names.size(), view.empty());
  if (!view.empty())
    for (int c : resolve_view(view, channel_names, 1, 1, key).channels) keep[static_cast<size_t>(c)] = true;
  return keep;
}

void blank_other_channels(const std::vector<bool>& keep, size_t pixels, float* frame) {
  for (size_t c = 0; c < keep.size(); ++c)
    if (!keep[c]) std::fill(frame + c * pixels, frame + (c + 1) * pixels, 0.0f);
}

}  // namespace cd
