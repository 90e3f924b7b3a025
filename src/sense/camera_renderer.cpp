// The front camera's renderer (sense/camera.hpp). The town's flat layers (ground, sidewalks,
// roads, what is painted, kerbs: all at z = 0) are drawn on the CPU: they are rasterized once into
// a map of 5 cm texels (coarser for a map over 1.6 km) in painter's order, and each pixel below the horizon looks up the texel
// where its centre's ray meets the ground (the rays are fixed in the camera's frame, so a frame
// costs a rotation and a lookup per pixel). That is what GL draws for a flat polygon without
// multisampling, a pixel being covered where its centre is, but sampled on the texel grid. The
// solids (vehicles, pedestrians, signal heads) are drawn by GL with depth on a transparent
// clear, and laid over the ground where GL covered a pixel. Faces are shaded on the CPU (ambient
// + the sun's diffuse share, flat per face) and lamps and brake lights are unlit colours, so GL's
// lighting state plays no part; fog is GL's exponential fog by eye depth on both sides.
#include <GL/gl.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <utility>
#include <vector>

#include "render/gl_context.hpp"
#include "sense/camera.hpp"
#include "sense/camera_projection.hpp"

namespace cd {

namespace {

struct Rgb {
  float r = 0, g = 0, b = 0;
};
// A colour channel in [0, 1] as GL stores it in 8 bits.
uint8_t unorm8(double v) { return static_cast<uint8_t>(std::lround(std::clamp(v, 0.0, 1.0) * 255.0)); }
Rgb from_hex(uint32_t c) {
  return {((c >> 16) & 255) / 255.0f, ((c >> 8) & 255) / 255.0f, (c & 255) / 255.0f};
}
constexpr double kMarkingWidth = 0.15, kKerbWidth = 0.25, kDash = 3.0, kGap = 3.0;

// Static layers farther than these from the camera are not drawn: the surfaces beyond 300 m (a
// 3.2 m lane there is about 1.5 pixels wide at the default 288 px and 90 degrees), what is
// painted and the kerbs beyond 80 m (a 0.15 m line there covers a fifth of a pixel's width).
constexpr double kSurfaceDrawDistance = 300.0, kPaintDrawDistance = 80.0;

// The quads of one flat layer, 4 corners each.
struct FlatLayer {
  std::vector<Vec2> corners;

  void quad(Vec2 a, Vec2 b, Vec2 c, Vec2 d) { corners.insert(corners.end(), {a, b, c, d}); }

  // A band along `pts` between the offsets `left` and `right` (metres to the left; right <
  // left): one quad per segment.
  void band(const Polyline& pts, double left, double right) {
    if (pts.size() < 2) return;
    const Polyline l = offset_polyline(pts, left), r = offset_polyline(pts, right);
    for (size_t i = 1; i < pts.size(); ++i) quad(l[i - 1], l[i], r[i], r[i - 1]);
  }

  // The dashed version of a band `width` wide centred on `pts`, in the dash pattern of the
  // bird's-eye view: along a segment of direction d from a, the painted stretches are where
  // dash_painted((a + d s) . d) holds, i.e. (a . d) + s within dash/2 of a multiple of the
  // period; one quad per stretch.
  void dashed(const Polyline& pts, double width, double dash, double gap) {
    const double period = dash + gap;
    for (size_t i = 1; i < pts.size(); ++i) {
      const Vec2 a = pts[i - 1], ab = pts[i] - a;
      const double len = ab.norm();
      if (len <= 0) continue;
      const Vec2 d = ab * (1.0 / len), n = Vec2{-d.y, d.x} * (0.5 * width);
      const double o = a.dot(d);
      for (double k = std::floor((o - 0.5 * dash) / period); k * period - 0.5 * dash < o + len;
           k += 1) {
        const double s0 = std::max(0.0, k * period - 0.5 * dash - o);
        const double s1 = std::min(len, k * period + 0.5 * dash - o);
        if (s1 <= s0) continue;
        const Vec2 p0 = a + d * s0, p1 = a + d * s1;
        quad(p0 + n, p1 + n, p1 - n, p0 - n);
      }
    }
  }
};

// The classes of the flat layers, in painter's order, and the sky (where a ray meets no ground).
enum FlatClass : uint8_t { kGround, kSidewalk, kRoad, kMarking, kKerb, kSky, kClasses };
constexpr double kTexel = 0.05;  // m: a 0.15 m marking is three texels wide
// A side of the raster has at most this many texels: a map over 1.6 km on a side gets coarser
// texels (3.3 km: 10 cm), so the raster stays under ~150 MB whatever the network.
constexpr double kMaxTexels = 32768;
constexpr int kTileBits = 4, kTile = 1 << kTileBits;  // 16 x 16 texels a tile

// The flat layers rasterized: each texel's byte holds, at its centre, the surface (ground,
// sidewalk or road: low nibble) and what lies on top of it (the surface, a marking or a kerb:
// high nibble), so the paint's shorter draw distance can show the surface beneath. Stored as
// tiles of kTile x kTile texels, a tile of one value as that value alone (most of a town is
// ground or road); outside the raster is ground.
class FlatRaster {
 public:
  FlatRaster() = default;
  // The texels covering [lo, hi].
  FlatRaster(Vec2 lo, Vec2 hi)
      : x0_(lo.x), y0_(lo.y),
        texel_(std::max(kTexel, std::max(hi.x - lo.x, hi.y - lo.y) / (kMaxTexels - 1))) {
    w_ = std::max(0, static_cast<int>(std::ceil((hi.x - lo.x) / texel_)) + 1);
    h_ = std::max(0, static_cast<int>(std::ceil((hi.y - lo.y) / texel_)) + 1);
    tw_ = (w_ + kTile - 1) >> kTileBits;
    const int th = (h_ + kTile - 1) >> kTileBits;
    tiles_.assign(static_cast<size_t>(tw_) * th, kUniform | 0u);
  }

  // Paints the triangle: `overlay` sets what lies on top, otherwise the surface too. A texel is
  // painted when its centre lies inside, rows and columns half-open (top-left) as GL's rule, so
  // two triangles sharing an edge leave neither a gap nor a double row between them.
  void triangle(Vec2 a, Vec2 b, Vec2 c, uint8_t cls, bool overlay) {
    Vec2 v[3] = {texel_coords(a), texel_coords(b), texel_coords(c)};
    std::sort(v, v + 3, [](Vec2 p, Vec2 q) { return p.y < q.y || (p.y == q.y && p.x < q.x); });
    const int j0 = std::max(0, static_cast<int>(std::ceil(v[0].y - 0.5)));
    const int j1 = std::min(h_, static_cast<int>(std::ceil(v[2].y - 0.5)));
    for (int j = j0; j < j1; ++j) {
      const double yc = j + 0.5;
      const double xa = edge_x(v[0], v[2], yc);
      const double xb = yc < v[1].y ? edge_x(v[0], v[1], yc) : edge_x(v[1], v[2], yc);
      const int i0 = std::max(0, static_cast<int>(std::ceil(std::min(xa, xb) - 0.5)));
      const int i1 = std::min(w_, static_cast<int>(std::ceil(std::max(xa, xb) - 0.5)));
      if (i0 < i1) span(j, i0, i1, cls, overlay);
    }
  }

  // Tiles left with one value become that value alone.
  void compact() {
    std::vector<uint8_t> pool;
    for (uint32_t& t : tiles_) {
      if (t & kUniform) continue;
      const uint8_t* texels = &pool_[static_cast<size_t>(t) << (2 * kTileBits)];
      if (std::all_of(texels, texels + kTile * kTile, [&](uint8_t x) { return x == texels[0]; })) {
        t = kUniform | texels[0];
        continue;
      }
      t = static_cast<uint32_t>(pool.size() >> (2 * kTileBits));
      pool.insert(pool.end(), texels, texels + kTile * kTile);
    }
    pool_ = std::move(pool);
  }

  // The network-frame point (x, y) in texels from the raster's corner.
  Vec2 texel_coords(Vec2 p) const { return {(p.x - x0_) / texel_, (p.y - y0_) / texel_}; }
  double texel() const { return texel_; }  // m

  // The byte of the texel holding the point at texel coordinates (fx, fy).
  uint8_t at(double fx, double fy) const {
    if (!(fx >= 0 && fy >= 0 && fx < w_ && fy < h_)) return kGround;
    const int i = static_cast<int>(fx), j = static_cast<int>(fy);
    const uint32_t t = tiles_[static_cast<size_t>(j >> kTileBits) * tw_ + (i >> kTileBits)];
    if (t & kUniform) return static_cast<uint8_t>(t);
    return pool_[(static_cast<size_t>(t) << (2 * kTileBits)) +
                 ((j & (kTile - 1)) << kTileBits) + (i & (kTile - 1))];
  }

 private:
  static constexpr uint32_t kUniform = 0x80000000u;

  // x where the edge from p to q (p below q) crosses the row's centre yc.
  static double edge_x(Vec2 p, Vec2 q, double yc) {
    return p.x + (yc - p.y) * (q.x - p.x) / (q.y - p.y);
  }
  static uint8_t painted(uint8_t old, uint8_t cls, bool overlay) {
    return overlay ? static_cast<uint8_t>((old & 0x0f) | (cls << 4))
                   : static_cast<uint8_t>(cls | (cls << 4));
  }
  void span(int j, int i0, int i1, uint8_t cls, bool overlay) {
    const int tj = j >> kTileBits, row = (j & (kTile - 1)) << kTileBits;
    for (int ti = i0 >> kTileBits; ti <= (i1 - 1) >> kTileBits; ++ti) {
      uint32_t& t = tiles_[static_cast<size_t>(tj) * tw_ + ti];
      if (t & kUniform) {
        const uint8_t u = static_cast<uint8_t>(t);
        if (painted(u, cls, overlay) == u) continue;
        t = static_cast<uint32_t>(pool_.size() >> (2 * kTileBits));
        pool_.resize(pool_.size() + kTile * kTile, u);
      }
      uint8_t* texels = &pool_[(static_cast<size_t>(t) << (2 * kTileBits)) + row];
      const int a = std::max(i0, ti << kTileBits), b = std::min(i1, (ti + 1) << kTileBits);
      for (int i = a; i < b; ++i) {
        uint8_t& x = texels[i & (kTile - 1)];
        x = painted(x, cls, overlay);
      }
    }
  }

  double x0_ = 0, y0_ = 0, texel_ = kTexel;
  int w_ = 0, h_ = 0, tw_ = 0;  // texels a side; tiles a row
  std::vector<uint32_t> tiles_;  // kUniform | value, or the tile's index in pool_
  std::vector<uint8_t> pool_;    // kTile x kTile texels per tile, rows of kTile
};

// Whether bounds can be in view: not wholly behind the camera, nor wholly outside either side
// of its horizontal field of view (with a margin), nor farther than `reach`. Conservative: bounds
// that pass may still be out of view.
bool in_view(const CameraFrame& f, double half_fov, Vec2 lo, Vec2 hi, double reach) {
  const Vec2 at{f.position.x, f.position.y};
  const Vec2 fwd = Vec2{f.forward.x, f.forward.y} * (1.0 / std::hypot(f.forward.x, f.forward.y));
  const Vec2 left{-fwd.y, fwd.x};
  const double c = std::cos(half_fov), s = std::sin(half_fov);
  // The wedge's edges' outward normals: beyond the left edge, beyond the right edge.
  const Vec2 out_left = left * c - fwd * s, out_right = left * (-c) - fwd * s;
  bool behind = true, past_left = true, past_right = true;
  for (const Vec2& corner : {lo, Vec2{hi.x, lo.y}, hi, Vec2{lo.x, hi.y}}) {
    const Vec2 d = corner - at;
    behind = behind && d.dot(fwd) < 0;
    past_left = past_left && d.dot(out_left) > 0;
    past_right = past_right && d.dot(out_right) > 0;
  }
  const double dx = std::max({lo.x - at.x, 0.0, at.x - hi.x});
  const double dy = std::max({lo.y - at.y, 0.0, at.y - hi.y});
  return !behind && !past_left && !past_right && std::hypot(dx, dy) <= reach;
}

Vec3 sun_direction(const CameraWeather& w) {
  const double az = w.sun_azimuth_deg * M_PI / 180.0, el = w.sun_elevation_deg * M_PI / 180.0;
  return {std::cos(el) * std::cos(az), std::cos(el) * std::sin(az), std::sin(el)};
}

// The solids' quads, drawn by GL in one call: 4 vertices a quad, each with the quad's colour.
// Every face is wound counter-clockwise seen from outside its box (a lamp or a brake light: seen
// from where it faces), so GL drops the faces turned away, which their box's front faces hide.
struct Quads {
  std::vector<float> xyz, rgb;
  float colour[3] = {0, 0, 0};
  // The colour of the following vertices, the sun's share `shade` applied.
  void set_colour(Rgb c, double shade = 1.0) {
    colour[0] = static_cast<float>(std::min(1.0, c.r * shade));
    colour[1] = static_cast<float>(std::min(1.0, c.g * shade));
    colour[2] = static_cast<float>(std::min(1.0, c.b * shade));
  }
  void vertex(double x, double y, double z) {
    xyz.insert(xyz.end(), {static_cast<float>(x), static_cast<float>(y), static_cast<float>(z)});
    rgb.insert(rgb.end(), colour, colour + 3);
  }
  size_t vertices() const { return xyz.size() / 3; }
};

// An upright box: centre, heading of its length axis, length, width, from z0 to z1; each face
// shaded by the sun (the bottom is never seen).
void solid_box(Quads& q, Vec2 c, double heading, double length, double width, double z0,
               double z1, Rgb colour, const CameraWeather& w) {
  const Vec3 sun = sun_direction(w);
  const Vec2 u{std::cos(heading), std::sin(heading)}, v{-u.y, u.x};
  const Vec2 hu = u * (0.5 * length), hv = v * (0.5 * width);
  const Vec2 corner[4] = {c + hu + hv, c - hu + hv, c - hu - hv, c + hu - hv};
  auto shade = [&](Vec3 n) { return w.ambient + (1 - w.ambient) * std::max(0.0, dot(n, sun)); };
  q.set_colour(colour, shade({0, 0, 1}));
  for (const Vec2& p : corner) q.vertex(p.x, p.y, z1);
  // Side k runs from corner k to corner k+1; its outward normal.
  const Vec2 normals[4] = {v, u * -1.0, v * -1.0, u};
  for (int k = 0; k < 4; ++k) {
    const Vec2 a = corner[k], b = corner[(k + 1) % 4];
    q.set_colour(colour, shade({normals[k].x, normals[k].y, 0}));
    q.vertex(a.x, a.y, z0);
    q.vertex(b.x, b.y, z0);
    q.vertex(b.x, b.y, z1);
    q.vertex(a.x, a.y, z1);
  }
}

// An unlit upright square facing `facing` (its normal), centred at (c, z), `across` wide and
// `tall` high.
void upright_quad(Quads& q, Vec2 c, double z, double facing, double across, double tall,
                  Rgb colour) {
  const Vec2 side = Vec2{-std::sin(facing), std::cos(facing)} * (0.5 * across);
  q.set_colour(colour);
  q.vertex(c.x - side.x, c.y - side.y, z - 0.5 * tall);
  q.vertex(c.x + side.x, c.y + side.y, z - 0.5 * tall);
  q.vertex(c.x + side.x, c.y + side.y, z + 0.5 * tall);
  q.vertex(c.x - side.x, c.y - side.y, z + 0.5 * tall);
}

const Rgb kLampOn[3] = {{1.0f, 0.05f, 0.02f}, {1.0f, 0.78f, 0.0f}, {0.1f, 1.0f, 0.25f}};
const Rgb kLampOff{0.13f, 0.13f, 0.12f};
const Rgb kHead{0.07f, 0.07f, 0.07f}, kPole{0.28f, 0.28f, 0.28f};
const Rgb kBrakeOn{1.0f, 0.08f, 0.05f}, kBrakeOff{0.32f, 0.03f, 0.03f};

}  // namespace

// The flat layers and, per pixel, where its centre's ray meets the ground relative to the
// camera (fixed in the camera's frame: the camera only turns with the ego's heading).
struct CameraRenderer::Ground {
  FlatRaster raster;
  // Per row (top first), for an ego at the origin heading east: the eye depth t where the ray
  // of the row's pixel centres meets the ground (0: the row is sky), its offset a along the
  // heading from the camera, and the offset b to the left of column c's ground point,
  // b0 + c db. Pitch turns the camera about its right axis only, so each row's ground points
  // lie on a line across the heading.
  std::vector<double> t, a, b0, db;
  // Per pixel, the layers it shows by its ground point's distance from the camera: 0 all, 1 the
  // surfaces, 2 the ground, 3 none (sky: above the horizon, or nearer than near_m or beyond
  // far_m).
  std::vector<uint8_t> level;
  // The weather the colours are for, and per row the RGB of each class as it shows there
  // (fog by the row's depth): kClasses x 3 bytes a row.
  const CameraWeather* coloured = nullptr;
  std::vector<uint8_t> colours;
  Quads solids;  // a frame's solids, kept to reuse its memory
};

CameraRenderer::CameraRenderer(const RoadMap& map, CameraConfig cfg)
    : cfg_(std::move(cfg)), weather_(nullptr), ground_(std::make_unique<Ground>()) {
  check_camera_config(cfg_);
  weather_ = &episode_weather(cfg_.weather, 0);
  gl_ = std::make_unique<GlContext>(cfg_.width, cfg_.height);

  // Sidewalks and walking areas, then the roads over them, then what is painted on the roads,
  // then the kerbs.
  FlatLayer sidewalks, roads, paint, kerbs;
  for (const LaneGeom& lane : map.lanes) {
    const Polyline pts = without_repeats(lane.shape);
    if (pts.size() < 2) continue;
    const double hw = lane.width / 2;
    switch (lane.kind) {
      case LaneKind::Sidewalk:
        sidewalks.band(pts, hw, -hw);
        for (double side : {1.0, -1.0})  // both edges, the kerb
          kerbs.band(offset_polyline(pts, side * hw), 0.5 * kKerbWidth, -0.5 * kKerbWidth);
        break;
      case LaneKind::WalkingArea:
        sidewalks.band(pts, hw, -hw);
        break;
      case LaneKind::Crossing:  // zebra stripes across the crossing's length
        paint.dashed(pts, lane.width, 0.5, 0.5);
        break;
      case LaneKind::Driving:
        roads.band(pts, hw, -hw);
        if (lane.internal) break;
        // As the bird's-eye view: the left border dashed, the right border solid unless a
        // neighbour lane draws it as its left border.
        paint.dashed(offset_polyline(pts, hw), kMarkingWidth, kDash, kGap);
        if (!lane.has_right_neighbour)
          paint.band(offset_polyline(pts, -hw), 0.5 * kMarkingWidth, -0.5 * kMarkingWidth);
        break;
    }
  }
  const std::pair<const FlatLayer*, uint8_t> layers[] = {
      {&sidewalks, kSidewalk}, {&roads, kRoad}, {&paint, kMarking}, {&kerbs, kKerb}};
  Vec2 lo{1e300, 1e300}, hi{-1e300, -1e300};
  for (const auto& [layer, cls] : layers)
    for (const Vec2& p : layer->corners) {
      lo = {std::min(lo.x, p.x), std::min(lo.y, p.y)};
      hi = {std::max(hi.x, p.x), std::max(hi.y, p.y)};
    }
  if (lo.x <= hi.x) {
    Ground& g = *ground_;
    g.raster = FlatRaster(lo, hi);
    for (const auto& [layer, cls] : layers) {
      const std::vector<Vec2>& q = layer->corners;
      for (size_t k = 0; k + 3 < q.size(); k += 4) {  // a quad as GL splits it
        g.raster.triangle(q[k], q[k + 1], q[k + 2], cls, cls >= kMarking);
        g.raster.triangle(q[k], q[k + 2], q[k + 3], cls, cls >= kMarking);
      }
    }
    g.raster.compact();
  }

  // Each row's ray, for an ego at the origin heading east: the camera's right is -y, so a
  // column moves the ground point along y only.
  const CameraFrame f = camera_frame(cfg_, Pose2{});
  Ground& g = *ground_;
  g.t.assign(cfg_.height, 0.0);
  g.a.assign(cfg_.height, 0.0);
  g.b0.assign(cfg_.height, 0.0);
  g.db.assign(cfg_.height, 0.0);
  g.level.assign(static_cast<size_t>(cfg_.width) * cfg_.height, 3);
  for (int row = 0; row < cfg_.height; ++row) {
    const double v = (f.cy - (row + 0.5)) / f.focal;
    const double dz = f.forward.z + v * f.up.z;  // right.z = 0: the same for every column
    if (dz >= 0) continue;
    const double t = -f.position.z / dz;  // the eye depth: the ray's share along forward is 1
    if (t < cfg_.near_m || t > cfg_.far_m) continue;
    g.t[row] = t;
    g.a[row] = t * (f.forward.x + v * f.up.x);
    g.db[row] = t * f.right.y / f.focal;
    g.b0[row] = g.db[row] * (0.5 - f.cx);
    for (int col = 0; col < cfg_.width; ++col) {
      const double dist = std::hypot(g.a[row], g.b0[row] + col * g.db[row]);
      g.level[static_cast<size_t>(row) * cfg_.width + col] =
          dist <= kPaintDrawDistance ? 0 : dist <= kSurfaceDrawDistance ? 1 : 2;
    }
  }
}

CameraRenderer::~CameraRenderer() = default;

void CameraRenderer::set_weather(const CameraWeather& weather) { weather_ = &weather; }

void CameraRenderer::render(const CameraScene& scene, uint8_t* out) {
  const CameraWeather& w = *weather_;
  Ground& g = *ground_;
  const int W = cfg_.width, H = cfg_.height;
  const size_t pixels = static_cast<size_t>(W) * H;

  // The classes' colours per row, once per weather.
  if (g.coloured != &w) {
    const float* base[kClasses] = {w.ground, w.sidewalk, w.road, w.marking, w.kerb, w.sky};
    g.colours.resize(static_cast<size_t>(H) * kClasses * 3);
    for (int row = 0; row < H; ++row) {
      // GL_EXP fog: the share of a fragment's own colour is exp(-density * eye depth).
      const double keep = std::exp(-w.fog_density * g.t[row]);
      for (int k = 0; k < kClasses; ++k)
        for (int ch = 0; ch < 3; ++ch)
          g.colours[(static_cast<size_t>(row) * kClasses + k) * 3 + ch] =
              unorm8(k == kSky ? w.sky[ch] : keep * base[k][ch] + (1 - keep) * w.sky[ch]);
    }
    g.coloured = &w;
  }

  // The flat layers: each pixel's ground point, its texel, its colour. Row by row, the ground
  // points step along a line: in texels, (x0 + col dx, y0 + col dy).
  const CameraFrame f = camera_frame(cfg_, scene.ego);
  const double ch = std::cos(scene.ego.heading), sh = std::sin(scene.ego.heading);
  const Vec2 camera{f.position.x, f.position.y};
  for (int row = 0; row < H; ++row) {
    const uint8_t* colour = &g.colours[static_cast<size_t>(row) * kClasses * 3];
    const size_t o0 = static_cast<size_t>(row) * W;
    if (g.t[row] == 0) {  // sky
      for (int k = 0; k < 3; ++k) std::memset(out + k * pixels + o0, colour[kSky * 3 + k], W);
      continue;
    }
    const double a = g.a[row], b0 = g.b0[row], db = g.db[row];
    const Vec2 start = g.raster.texel_coords(
        {camera.x + a * ch - b0 * sh, camera.y + a * sh + b0 * ch});
    const double dx = -db * sh / g.raster.texel(), dy = db * ch / g.raster.texel();
    const uint8_t* level = &g.level[o0];
    for (int col = 0; col < W; ++col) {
      uint8_t cls = kSky;
      if (level[col] < 2) {
        const uint8_t t = g.raster.at(start.x + col * dx, start.y + col * dy);
        cls = level[col] == 0 ? t >> 4 : t & 0x0f;
      } else if (level[col] == 2) {
        cls = kGround;
      }
      const uint8_t* c = colour + cls * 3;
      out[o0 + col] = c[0];
      out[pixels + o0 + col] = c[1];
      out[2 * pixels + o0 + col] = c[2];
    }
  }

  // The solids, each left out when it cannot be in view; GL is not called when none can.
  const double half_fov = 0.5 * cfg_.hfov_deg * M_PI / 180.0 + 0.1;
  auto visible = [&](Vec2 c, double r) {
    return in_view(f, half_fov, c - Vec2{r, r}, c + Vec2{r, r}, cfg_.far_m);
  };
  Quads& q = g.solids;
  q.xyz.clear();
  q.rgb.clear();
  for (const CameraScene::Vehicle& v : scene.vehicles) {
    const Box& b = v.box;
    if (!visible(b.center, 0.5 * (b.length + b.width))) continue;
    solid_box(q, b.center, b.heading, b.length, b.width, 0.0, v.height, from_hex(v.colour), w);
    // Brake lights on the rear face, just behind it.
    const Vec2 u{std::cos(b.heading), std::sin(b.heading)}, side{-u.y, u.x};
    const Vec2 rear = b.center - u * (0.5 * b.length + 0.02);
    const double lateral = std::max(0.0, 0.5 * b.width - 0.25);
    for (double sd : {1.0, -1.0})
      upright_quad(q, rear + side * (sd * lateral), 0.85, b.heading + M_PI, 0.25, 0.18,
                   v.braking ? kBrakeOn : kBrakeOff);
  }
  for (const CameraScene::Pedestrian& ped : scene.pedestrians)
    if (visible(ped.box.center, ped.box.length + ped.box.width))
      solid_box(q, ped.box.center, ped.box.heading, ped.box.length, ped.box.width, 0.0,
                ped.height, from_hex(ped.colour), w);
  const LightHeadGeometry& lg = kLightHead;
  for (const CameraScene::Light& l : scene.lights) {
    if (!visible(l.position, 1.0)) continue;
    solid_box(q, l.position, l.facing, 0.12, 0.12, 0.0, lg.pole_height, kPole, w);
    solid_box(q, l.position, l.facing, lg.head_depth, lg.head_width, lg.pole_height,
              lg.pole_height + lg.head_height, kHead, w);
    const int lit = l.state == 'r' ? 0 : l.state == 'y' ? 1 : 2;
    const Vec2 face = l.position + Vec2{std::cos(l.facing), std::sin(l.facing)} *
                                       (0.5 * lg.head_depth + 0.01);
    for (int lamp = 0; lamp < 3; ++lamp)
      upright_quad(q, face, lg.lamp_centre_height(lamp), l.facing, lg.lamp_size, lg.lamp_size,
                   lamp == lit ? kLampOn[lamp] : kLampOff);
  }
  if (q.vertices() == 0) return;

  // The pixels the solids can cover: the bounds of their vertices' projections (every pixel
  // when one lies behind the near plane, where the projection does not bound the clipped face).
  int r0 = 0, r1 = H, c0 = 0, c1 = W;
  {
    double lo_r = 1e300, hi_r = -1e300, lo_c = 1e300, hi_c = -1e300;
    bool bounded = true;
    for (size_t k = 0; k < q.vertices() && bounded; ++k) {
      const auto px =
          camera_project(f, cfg_.near_m, {q.xyz[3 * k], q.xyz[3 * k + 1], q.xyz[3 * k + 2]});
      if (!px) {
        bounded = false;
        break;
      }
      lo_r = std::min(lo_r, px->row), hi_r = std::max(hi_r, px->row);
      lo_c = std::min(lo_c, px->col), hi_c = std::max(hi_c, px->col);
    }
    if (bounded) {
      r0 = static_cast<int>(std::clamp(std::floor(lo_r) - 1, 0.0, double(H)));
      r1 = static_cast<int>(std::clamp(std::ceil(hi_r) + 1, 0.0, double(H)));
      c0 = static_cast<int>(std::clamp(std::floor(lo_c) - 1, 0.0, double(W)));
      c1 = static_cast<int>(std::clamp(std::ceil(hi_c) + 1, 0.0, double(W)));
    }
  }
  if (r0 >= r1 || c0 >= c1) return;

  gl_->make_current();
  glViewport(0, 0, W, H);
  glDisable(GL_LIGHTING);
  glDisable(GL_DITHER);
  glDisable(GL_BLEND);
  glEnable(GL_CULL_FACE);
  glFrontFace(GL_CCW);
  glCullFace(GL_BACK);
  glShadeModel(GL_FLAT);
  glEnable(GL_SCISSOR_TEST);  // only the solids' bounds are cleared, drawn and read
  glScissor(c0, H - r1, c1 - c0, r1 - r0);
  glClearColor(0.0f, 0.0f, 0.0f, 0.0f);  // alpha 0: not covered, the ground shows
  glClearDepth(1.0);
  glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);

  // The projection of sense/camera.hpp's pixel convention: window x = col, window y = H - row.
  const double n = cfg_.near_m, k = n / f.focal;
  glMatrixMode(GL_PROJECTION);
  glLoadIdentity();
  glFrustum(-f.cx * k, (W - f.cx) * k, -(H - f.cy) * k, f.cy * k, n, cfg_.far_m);
  // Eye coordinates: x right, y up, -z forward.
  const Vec3 p = f.position;
  const double view[16] = {f.right.x, f.up.x, -f.forward.x, 0,
                           f.right.y, f.up.y, -f.forward.y, 0,
                           f.right.z, f.up.z, -f.forward.z, 0,
                           -dot(f.right, p), -dot(f.up, p), dot(f.forward, p), 1};
  glMatrixMode(GL_MODELVIEW);
  glLoadMatrixd(view);
  if (w.fog_density > 0) {
    glEnable(GL_FOG);
    glFogi(GL_FOG_MODE, GL_EXP);
    glFogf(GL_FOG_DENSITY, static_cast<float>(w.fog_density));
    const float fog[4] = {w.sky[0], w.sky[1], w.sky[2], 1.0f};
    glFogfv(GL_FOG_COLOR, fog);
  } else {
    glDisable(GL_FOG);
  }
  glEnable(GL_DEPTH_TEST);
  glDepthFunc(GL_LESS);
  glEnableClientState(GL_VERTEX_ARRAY);
  glEnableClientState(GL_COLOR_ARRAY);
  glVertexPointer(3, GL_FLOAT, 0, q.xyz.data());
  glColorPointer(3, GL_FLOAT, 0, q.rgb.data());
  glDrawArrays(GL_QUADS, 0, static_cast<GLsizei>(q.vertices()));
  glDisableClientState(GL_COLOR_ARRAY);
  glDisableClientState(GL_VERTEX_ARRAY);
  glDisable(GL_SCISSOR_TEST);
  // Where GL covered a pixel (alpha 1), its colour replaces the ground's.
  const uint8_t* rows = gl_->finish_rgba();
  for (int row = r0; row < r1; ++row) {
    const uint8_t* src = rows + (static_cast<size_t>(H - 1 - row) * W + c0) * 4;
    for (int col = c0; col < c1; ++col, src += 4) {
      if (src[3] == 0) continue;
      const size_t o = static_cast<size_t>(row) * W + col;
      out[o] = src[0];
      out[pixels + o] = src[1];
      out[2 * pixels + o] = src[2];
    }
  }
}

}  // namespace cd
