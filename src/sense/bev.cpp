#include "sense/bev.hpp"

#include "core/png.hpp"
#include "sense/bev_colour.hpp"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>

#include "core/atomic_file.hpp"
#include "core/bitplanes.hpp"
#include "core/error.hpp"

#define STB_IMAGE_WRITE_IMPLEMENTATION
#define STB_IMAGE_WRITE_STATIC  // keeps stb's symbols private to this file
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wunused-function"
#pragma GCC diagnostic ignored "-Wmissing-field-initializers"
#include <stb/stb_image_write.h>
#pragma GCC diagnostic pop

namespace cd {

namespace {

constexpr uint8_t kDrivableBit = 1, kMarkingsBit = 2, kRouteBit = 4;

// Half the drawn width of a marking line. Nearest-neighbour sampling at metres_per_pixel
// misses a thinner line depending on the pose, and the global raster's own quantisation
// shifts each painted pixel by up to gres/sqrt(2) across the line; this width still leaves
// at least one output pixel per image row and column that crosses the line, so solid lines
// stay connected at every pose.
double marking_half_width(const BevConfig& cfg, double gres) {
  return 0.5 * std::max(cfg.marking_width, cfg.metres_per_pixel + gres * std::sqrt(2.0));
}

// Sets `bit` in the pixels of the packed H x W image whose centres lie in the rectangle
// centred at (rc, cc) with unit axis (ur, uc) and half-extents hl along it and hw across it,
// all in pixel units.
void fill_rect(uint8_t* img, int H, int W, uint8_t bit, double rc, double cc, double ur,
               double uc, double hl, double hw) {
  const double er = hl * std::abs(ur) + hw * std::abs(uc);
  const double ec = hl * std::abs(uc) + hw * std::abs(ur);
  // Clip in floating point first: far-away boxes must not overflow the int conversion.
  const double r0 = std::max(0.0, std::ceil(rc - er - 0.5));
  const double r1 = std::min(H - 1.0, std::floor(rc + er - 0.5));
  const double c0 = std::max(0.0, std::ceil(cc - ec - 0.5));
  const double c1 = std::min(W - 1.0, std::floor(cc + ec - 0.5));
  if (!(r0 <= r1 && c0 <= c1)) return;
  for (int r = int(r0); r <= int(r1); ++r) {
    const double dr = r + 0.5 - rc;
    for (int c = int(c0); c <= int(c1); ++c) {
      const double dc = c + 0.5 - cc;
      if (std::abs(dr * ur + dc * uc) <= hl && std::abs(dc * ur - dr * uc) <= hw)
        img[size_t(r) * W + c] |= bit;
    }
  }
}

}  // namespace

const std::array<std::string, kBevChannelCount>& bev_channel_names() {
  static const std::array<std::string, kBevChannelCount> names = {
      "drivable", "markings", "route", "vehicles", "pedestrians",
      "light_red", "light_green", "light_yield"};
  return names;
}

BevRenderer::BevRenderer(const RoadMap& map, BevConfig cfg) : map_(map), cfg_(cfg) {
  if (cfg_.height < 1 || cfg_.width < 1 || !(cfg_.metres_per_pixel > 0) ||
      cfg_.static_supersample < 1 || !(cfg_.ego_row_fraction >= 0) ||
      !(cfg_.ego_row_fraction <= 1) || !(cfg_.dash_length > 0) || !(cfg_.dash_gap >= 0) ||
      !(cfg_.marking_width >= 0))
    throw Error("bev: invalid BevConfig (need height, width, metres_per_pixel, "
                "static_supersample, dash_length > 0, dash_gap, marking_width >= 0, "
                "ego_row_fraction in [0, 1])");
  gres_ = cfg_.metres_per_pixel / cfg_.static_supersample;

  Vec2 lo = map.min, hi = map.max;
  if (lo.x > hi.x || lo.y > hi.y) lo = hi = Vec2{};  // no lane points: an empty raster
  double max_half_width = 0;
  for (const LaneGeom& lane : map.lanes) max_half_width = std::max(max_half_width, lane.width / 2);
  // The view reaches this far from the ego (farthest image corner); with that margin an
  // ego anywhere on the map samples inside the raster and render() takes its unchecked path.
  const double row_e = cfg_.height * cfg_.ego_row_fraction, col_e = cfg_.width / 2.0;
  const double view = cfg_.metres_per_pixel * std::hypot(std::max(row_e, cfg_.height - row_e),
                                                         std::max(col_e, cfg_.width - col_e));
  const double margin = view + max_half_width + marking_half_width(cfg_, gres_) + 2 * gres_;
  origin_ = {lo.x - margin, hi.y + margin};
  const double gw = std::ceil((hi.x - lo.x + 2 * margin) / gres_);
  const double gh = std::ceil((hi.y - lo.y + 2 * margin) / gres_);
  if (gw * gh > double(1u << 30))
    throw Error("bev: the map needs a " + std::to_string(int64_t(gw)) + " x " +
                std::to_string(int64_t(gh)) +
                " static raster; raise metres_per_pixel or lower static_supersample");
  gw_ = int(gw);
  gh_ = int(gh);
  layers_.assign(size_t(gw_) * gh_, 0);

  for (const LaneGeom& lane : map.lanes) {
    if (lane.kind != LaneKind::Driving) continue;
    fill_lane(lane, kDrivableBit);
    if (!lane.internal) draw_markings(lane);
  }
}

void BevRenderer::stroke(Vec2 a, Vec2 b, double half_width, bool cap_a, bool cap_b,
                         bool dashed, uint8_t bit) {
  const Vec2 ab = b - a;
  const double len = ab.norm();
  const Vec2 d = len > 0 ? ab * (1.0 / len) : Vec2{1, 0};  // degenerate: only caps paint
  const double hw2 = half_width * half_width;
  const double period = cfg_.dash_length + cfg_.dash_gap;

  // Pixel (r, c) has its centre at (origin.x + (c + 0.5) g, origin.y - (r + 0.5) g).
  const double x0 = std::min(a.x, b.x) - half_width, x1 = std::max(a.x, b.x) + half_width;
  const double y0 = std::min(a.y, b.y) - half_width, y1 = std::max(a.y, b.y) + half_width;
  const int c0 = std::max(0, int(std::ceil((x0 - origin_.x) / gres_ - 0.5)));
  const int c1 = std::min(gw_ - 1, int(std::floor((x1 - origin_.x) / gres_ - 0.5)));
  const int r0 = std::max(0, int(std::ceil((origin_.y - y1) / gres_ - 0.5)));
  const int r1 = std::min(gh_ - 1, int(std::floor((origin_.y - y0) / gres_ - 0.5)));
  for (int r = r0; r <= r1; ++r) {
    const double y = origin_.y - (r + 0.5) * gres_;
    for (int c = c0; c <= c1; ++c) {
      const double x = origin_.x + (c + 0.5) * gres_;
      const Vec2 p{x - a.x, y - a.y};
      const double t = p.dot(d);
      const Vec2 q = p - ab;
      const bool inside = (len > 0 && t >= 0 && t <= len && std::abs(d.cross(p)) <= half_width) ||
                          (cap_a && p.dot(p) <= hw2) || (cap_b && q.dot(q) <= hw2);
      if (!inside) continue;
      if (dashed && !dash_painted(Vec2{x, y}.dot(d), cfg_.dash_length, period)) continue;
      layers_[size_t(r) * gw_ + c] |= bit;
    }
  }
}

void BevRenderer::fill_lane(const LaneGeom& lane, uint8_t bit) {
  // A disc at every inner joint closes the wedge that two rectangles leave on the outside of
  // a bend; the lane's two ends stay square so lanes do not bulge into junctions.
  const Polyline& s = lane.shape;
  for (size_t i = 1; i < s.size(); ++i)
    stroke(s[i - 1], s[i], lane.width / 2, i > 1, false, false, bit);
}

void BevRenderer::draw_markings(const LaneGeom& lane) {
  const Polyline pts = without_repeats(lane.shape);
  if (pts.size() < 2) return;
  const double hw = marking_half_width(cfg_, gres_);
  // Left border: a divider or the centre line towards the opposite direction, dashed either
  // way. Right border: the road edge, unless a neighbour lane draws it as its left border.
  const Polyline left = offset_polyline(pts, lane.width / 2);
  for (size_t i = 1; i < left.size(); ++i)
    stroke(left[i - 1], left[i], hw, true, true, true, kMarkingsBit);
  if (lane.has_right_neighbour) return;
  const Polyline right = offset_polyline(pts, -lane.width / 2);
  for (size_t i = 1; i < right.size(); ++i)
    stroke(right[i - 1], right[i], hw, true, true, false, kMarkingsBit);
}

void BevRenderer::set_route(const std::vector<std::string>& lane_ids) {
  // Resolve every id before touching the layer, so a bad id leaves the old route intact.
  std::vector<const LaneGeom*> lanes;
  lanes.reserve(lane_ids.size());
  for (const std::string& id : lane_ids) {
    const LaneGeom* lane = map_.find(id);
    if (!lane) throw Error("bev: route lane '" + id + "' is not in the map");
    lanes.push_back(lane);
  }
  for (uint8_t& v : layers_) v &= uint8_t(~kRouteBit);
  for (const LaneGeom* lane : lanes) fill_lane(*lane, kRouteBit);
}

void BevRenderer::render(const BevScene& scene, uint8_t* out) const {
  thread_local std::vector<uint8_t> packed;
  packed.resize(size_t(cfg_.height) * cfg_.width);
  render_packed(scene, packed.data());
  unpack_planes(packed.data(), packed.size(), kBevChannelCount, out);
}

void BevRenderer::render_packed(const BevScene& scene, uint8_t* out) const {
  static_assert(kBevChannelCount <= kMaxPackedChannels);
  static_assert(kDrivableBit == 1 << kBevDrivable && kMarkingsBit == 1 << kBevMarkings &&
                kRouteBit == 1 << kBevRoute);
  const int H = cfg_.height, W = cfg_.width;
  const double mpp = cfg_.metres_per_pixel;
  const double row_e = H * cfg_.ego_row_fraction, col_e = W / 2.0;
  const double ch = std::cos(scene.ego.heading), sh = std::sin(scene.ego.heading);
  const Vec2 fwd{ch, sh}, left{-sh, ch};

  // Static layers. The global-raster position (column gx, row gy) of output pixel centre
  // (r, c) is affine in (r, c): a start per row plus a step per column.
  const double k = mpp / gres_;
  const double f0 = (row_e - 0.5) * mpp, l0 = (col_e - 0.5) * mpp;
  const Vec2 e = scene.ego.pos;
  const double gx00 = (e.x - origin_.x + f0 * ch - l0 * sh) / gres_;
  const double gy00 = (origin_.y - e.y - f0 * sh - l0 * ch) / gres_;
  const double gx_dr = -k * ch, gy_dr = k * sh, gx_dc = k * sh, gy_dc = k * ch;

  // Affine, so the extremes are at the corners; half a pixel of slack absorbs rounding.
  bool inside = true;
  for (int r : {0, H - 1})
    for (int c : {0, W - 1}) {
      const double gx = gx00 + r * gx_dr + c * gx_dc, gy = gy00 + r * gy_dr + c * gy_dc;
      inside = inside && gx >= 0.5 && gx < gw_ - 0.5 && gy >= 0.5 && gy < gh_ - 0.5;
    }

  const uint8_t* layers = layers_.data();
  const size_t gw = size_t(gw_);
  for (int r = 0; r < H; ++r) {
    const double bx = gx00 + r * gx_dr, by = gy00 + r * gy_dr;
    const size_t row = size_t(r) * W;
    // The static layers are stored with the same bits as the output: one read per pixel.
    uint8_t* packed = out + row;
    if (inside) {
      // Fixed point (32 fractional bits): one add per coordinate and pixel. Coordinates are
      // non-negative here, so the shift is floor.
      constexpr double kOne = 4294967296.0;
      int64_t fx = int64_t(bx * kOne), fy = int64_t(by * kOne);
      const int64_t dx = int64_t(gx_dc * kOne), dy = int64_t(gy_dc * kOne);
      for (int c = 0; c < W; ++c, fx += dx, fy += dy)
        packed[c] = layers[size_t(fy >> 32) * gw + size_t(fx >> 32)];
    } else {
      for (int c = 0; c < W; ++c) {
        const double gx = bx + c * gx_dc, gy = by + c * gy_dc;
        const bool in = gx >= 0 && gx < gw_ && gy >= 0 && gy < gh_;
        packed[c] = in ? layers[size_t(gy) * gw + size_t(gx)] : 0;
      }
    }
  }

  // Dynamic content, straight in image space. A network-frame vector w moves a point by
  // (-w.fwd, -w.left) / mpp pixels in (row, col).
  auto draw_box = [&](const Box& box, BevChannel ch, double min_half_px) {
    const Vec2 d = box.center - e;
    const Vec2 u{std::cos(box.heading), std::sin(box.heading)};
    fill_rect(out, H, W, uint8_t(1 << ch), row_e - d.dot(fwd) / mpp, col_e - d.dot(left) / mpp,
              -u.dot(fwd), -u.dot(left), std::max(box.length / 2 / mpp, min_half_px),
              std::max(box.width / 2 / mpp, min_half_px));
  };
  for (const Box& v : scene.vehicles) draw_box(v, kBevVehicles, 0.0);
  // At least 2 x 2 pixels: a pedestrian is narrower than a pixel at the default scale.
  for (const Box& p : scene.pedestrians) draw_box(p, kBevPedestrians, 1.0);

  for (const BevScene::StopLine& s : scene.stop_lines) {
    if (s.channel != kBevLightRed && s.channel != kBevLightGreen && s.channel != kBevLightYield)
      throw Error("bev: stop line channel " + std::to_string(int(s.channel)) +
                  " is not a traffic-light channel");
    const Vec2 ab = s.b - s.a;
    const double len = ab.norm();
    const Vec2 u = len > 0 ? ab * (1.0 / len) : Vec2{1, 0};
    const Vec2 d = (s.a + s.b) * 0.5 - e;
    fill_rect(out, H, W, uint8_t(1 << s.channel), row_e - d.dot(fwd) / mpp,
              col_e - d.dot(left) / mpp, -u.dot(fwd), -u.dot(left), len / 2 / mpp,
              std::max(0.5 / mpp, 1.0));
  }
}

std::vector<uint8_t> frame_picture(const uint8_t* frame, int channels, int height, int width,
                                   bool rgb) {
  if (!rgb) return bev_colour(frame, channels, height, width);
  if (channels != 3) throw Error("an RGB frame has 3 channels, not " + std::to_string(channels));
  std::vector<uint8_t> out;
  append_rgb_rows(frame, height, width, out);
  return out;
}

std::vector<uint8_t> bev_colour(const uint8_t* frame, int channels, int height, int width) {
  if (channels < 1 || channels > kBevChannelCount || height < 1 || width < 1)
    throw Error("bev: cannot colour a " + std::to_string(channels) + " x " +
                std::to_string(height) + " x " + std::to_string(width) + " frame");
  struct Rgb {
    uint8_t r, g, b;
  };
  static constexpr Rgb kBackground{35, 35, 35};
  static constexpr std::array<Rgb, kBevChannelCount> kColour = {{
      {95, 95, 95},    // drivable
      {240, 240, 240}, // markings
      {40, 90, 230},   // route (blended, so the road stays visible under it)
      {0, 210, 230},   // vehicles
      {230, 40, 230},  // pedestrians
      {230, 30, 30},   // light_red
      {40, 200, 60},   // light_green
      {255, 150, 0},   // light_yield
  }};

  const size_t plane = size_t(height) * width;
  std::vector<Rgb> small(plane, kBackground);
  for (int ch = 0; ch < channels; ++ch) {
    const Rgb col = kColour[ch];
    for (size_t i = 0; i < plane; ++i) {
      if (!frame[ch * plane + i]) continue;
      Rgb& px = small[i];
      if (ch == kBevRoute)
        px = {uint8_t((px.r + col.r) / 2), uint8_t((px.g + col.g) / 2),
              uint8_t((px.b + col.b) / 2)};
      else
        px = col;
    }
  }
  std::vector<uint8_t> rgb(plane * 3);
  for (size_t i = 0; i < plane; ++i) {
    rgb[i * 3] = small[i].r;
    rgb[i * 3 + 1] = small[i].g;
    rgb[i * 3 + 2] = small[i].b;
  }
  return rgb;
}

void write_bev_png(const std::string& path, const uint8_t* frame, int channels, int height,
                   int width, int scale) {
  if (channels < 1 || channels > kBevChannelCount || height < 1 || width < 1 || scale < 1 ||
      int64_t(width) * scale * 3 > INT32_MAX || int64_t(height) * scale > INT32_MAX)
    throw Error("bev: cannot draw a " + std::to_string(channels) + " x " +
                std::to_string(height) + " x " + std::to_string(width) + " frame at scale " +
                std::to_string(scale));
  const std::vector<uint8_t> small = bev_colour(frame, channels, height, width);
  const int big_w = width * scale, big_h = height * scale;
  std::vector<uint8_t> big(size_t(big_w) * big_h * 3);
  for (int y = 0; y < big_h; ++y)
    for (int x = 0; x < big_w; ++x) {
      const uint8_t* px = &small[(size_t(y / scale) * width + x / scale) * 3];
      uint8_t* o = &big[(size_t(y) * big_w + x) * 3];
      o[0] = px[0];
      o[1] = px[1];
      o[2] = px[2];
    }

  std::string png;
  auto append = [](void* ctx, void* data, int size) {
    static_cast<std::string*>(ctx)->append(static_cast<const char*>(data), size_t(size));
  };
  if (!stbi_write_png_to_func(append, &png, big_w, big_h, 3, big.data(), big_w * 3))
    throw IoError("cannot encode PNG for " + path);

  const std::string tmp = temp_path_for(path);
  {
    std::ofstream f(tmp, std::ios::binary | std::ios::trunc);
    if (!f) throw IoError("cannot write " + tmp + ": " + std::strerror(errno));
    f.write(png.data(), std::streamsize(png.size()));
    f.close();
    if (!f) {
      std::remove(tmp.c_str());
      throw IoError("write failed for " + tmp);
    }
  }
  commit_temp_file(tmp, path);
}

}  // namespace cd
