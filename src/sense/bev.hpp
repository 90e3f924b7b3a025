#pragma once
// Ego-centred, heading-up bird's-eye raster (SPEC section 1).
//
// Pixel convention (tests rely on it): the output is C x H x W uint8, row-major, values 0 or
// 255. The ego's reference point (the centre of its box) sits at pixel coordinates
// (row_e, col_e) = (H * ego_row_fraction, W / 2), measured in pixel units from the top-left
// corner of the image. A point at `forward` metres ahead of the ego and `left` metres to its
// left lands at continuous pixel coordinates
//     row = row_e - forward / metres_per_pixel,  col = col_e - left / metres_per_pixel,
// i.e. pixel (r, c) covers rows [r, r+1) and cols [c, c+1); its centre is (r + 0.5, c + 0.5).
// Up in the image is the ego's heading, right in the image is the ego's right.
#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "core/geometry.hpp"
#include "world/road_map.hpp"

namespace cd {

enum BevChannel : int {
  kBevDrivable = 0,    // driving lanes (normal and internal), not sidewalks
  kBevMarkings,        // lane markings: solid road borders, dashed dividers between lanes
  kBevRoute,           // the ego's route lanes
  kBevVehicles,        // other vehicles (the ego is not drawn)
  kBevPedestrians,     // pedestrians
  kBevLightRed,        // stop line of the ego's next link when red or yellow
  kBevLightGreen,      // ... when green with priority (SUMO 'G')
  kBevLightYield,      // ... when green without priority, must yield (SUMO 'g')
  kBevChannelCount
};

const std::array<std::string, kBevChannelCount>& bev_channel_names();

struct BevConfig {
  int height = 64;
  int width = 64;
  double metres_per_pixel = 0.5;
  double ego_row_fraction = 0.75;  // ego sits 3/4 down the image: more view ahead than behind
  double dash_length = 3.0;        // m, painted part of a dashed divider
  double dash_gap = 3.0;           // m
  double marking_width = 0.25;     // m; drawn at least ~1 output pixel wide so lines never break
  int static_supersample = 2;      // static layers are pre-rasterised at mpp / this factor
};

// Dynamic content of one frame, in the network frame.
struct BevScene {
  Pose2 ego;                       // centre of the ego box and its heading
  std::vector<Box> vehicles;       // other vehicles
  std::vector<Box> pedestrians;
  struct StopLine {
    Vec2 a, b;                     // endpoints across the lane, network frame
    BevChannel channel;            // kBevLightRed, kBevLightGreen or kBevLightYield
  };
  std::vector<StopLine> stop_lines;
};

class BevRenderer {
 public:
  // Pre-rasterises drivable area and markings of the whole map (done once per town).
  BevRenderer(const RoadMap& map, BevConfig cfg);

  // Pre-rasterises the route layer: the given lanes (ids into the map) are drawn at full
  // lane width. Called once per episode.
  void set_route(const std::vector<std::string>& lane_ids);

  // Writes C*H*W bytes (planes of 0/255) to out.
  void render(const BevScene& scene, uint8_t* out) const;
  // Writes H*W bytes to out, bit c of each byte = channel c (core/bitplanes.hpp): the same
  // frame 8x smaller, what recorders keep.
  void render_packed(const BevScene& scene, uint8_t* out) const;

  const BevConfig& config() const { return cfg_; }
  size_t frame_bytes() const { return size_t(kBevChannelCount) * cfg_.height * cfg_.width; }

 private:
  // Strokes segment a-b into the global raster (bits `bit`): pixels whose centre lies within
  // half_width of the segment's body, plus discs at the ends that have caps; `dashed` keeps
  // only the painted part of the network-frame dash pattern.
  void stroke(Vec2 a, Vec2 b, double half_width, bool cap_a, bool cap_b, bool dashed,
              uint8_t bit);
  void fill_lane(const LaneGeom& lane, uint8_t bit);  // full lane width, gap-free at bends
  void draw_markings(const LaneGeom& lane);

  const RoadMap& map_;
  BevConfig cfg_;
  // Global rasters at metres_per_pixel / static_supersample covering the map bounds.
  Vec2 origin_;  // network coordinates of the global raster's (0,0) corner (min x, max y)
  int gw_ = 0, gh_ = 0;
  double gres_ = 0;
  // The three static layers packed one bit each (drivable 1, markings 2, route 4), so that
  // render() does one lookup per pixel instead of three.
  std::vector<uint8_t> layers_;
};

// Writes a C x H x W frame as one PNG: channels composited in colour on a dark background
// (for people to look at, not for training).
void write_bev_png(const std::string& path, const uint8_t* frame, int channels, int height,
                   int width, int scale = 4);

}  // namespace cd
