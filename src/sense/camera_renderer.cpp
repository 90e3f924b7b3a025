// The front camera's GL side (sense/camera.hpp): the town's flat layers in one display list,
// drawn in painter's order without depth, then the boxes of vehicles, pedestrians and signal
// heads with depth. Faces are shaded on the CPU (ambient + the sun's diffuse share, flat per
// face) and lamps and brake lights are unlit colours, so GL's lighting state plays no part.
#include <GL/gl.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <utility>
#include <vector>

#include "render/gl_context.hpp"
#include "sense/camera.hpp"

namespace cd {

namespace {

struct Rgb {
  float r = 0, g = 0, b = 0;
};
Rgb rgb(const float c[3]) { return {c[0], c[1], c[2]}; }
Rgb from_hex(uint32_t c) {
  return {((c >> 16) & 255) / 255.0f, ((c >> 8) & 255) / 255.0f, (c & 255) / 255.0f};
}
void set_colour(Rgb c, double shade = 1.0) {
  glColor3f(static_cast<float>(std::min(1.0, c.r * shade)),
            static_cast<float>(std::min(1.0, c.g * shade)),
            static_cast<float>(std::min(1.0, c.b * shade)));
}

constexpr double kMarkingWidth = 0.15, kKerbWidth = 0.25, kDash = 3.0, kGap = 3.0;

// The quads of one flat layer, grouped by the map cell their centre lies in (kCell m squares).
constexpr double kCell = 80.0;
// Static layers farther than these from the camera are not drawn: the surfaces beyond 300 m (a
// 3.2 m lane there is about 1.5 pixels wide at the default 288 px and 90 degrees), what is
// painted and the kerbs beyond 80 m (a 0.15 m line there covers a fifth of a pixel's width).
constexpr double kSurfaceDrawDistance = 300.0, kPaintDrawDistance = 80.0;

struct FlatLayer {
  std::map<std::pair<long, long>, std::vector<Vec2>> cells;  // 4 corners per quad

  void quad(Vec2 a, Vec2 b, Vec2 c, Vec2 d) {
    const Vec2 m = (a + b + c + d) * 0.25;
    auto& q = cells[{static_cast<long>(std::floor(m.x / kCell)),
                     static_cast<long>(std::floor(m.y / kCell))}];
    q.insert(q.end(), {a, b, c, d});
  }

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

// An upright box: centre, heading of its length axis, length, width, from z0 to z1; each face
// shaded by the sun (the bottom is never seen).
void solid_box(Vec2 c, double heading, double length, double width, double z0, double z1,
               Rgb colour, const CameraWeather& w) {
  const Vec3 sun = sun_direction(w);
  const Vec2 u{std::cos(heading), std::sin(heading)}, v{-u.y, u.x};
  const Vec2 hu = u * (0.5 * length), hv = v * (0.5 * width);
  const Vec2 corner[4] = {c + hu + hv, c - hu + hv, c - hu - hv, c + hu - hv};
  auto shade = [&](Vec3 n) { return w.ambient + (1 - w.ambient) * std::max(0.0, dot(n, sun)); };
  set_colour(colour, shade({0, 0, 1}));
  for (const Vec2& p : corner) glVertex3d(p.x, p.y, z1);
  // Side k runs from corner k to corner k+1; its outward normal.
  const Vec2 normals[4] = {v, u * -1.0, v * -1.0, u};
  for (int k = 0; k < 4; ++k) {
    const Vec2 a = corner[k], b = corner[(k + 1) % 4];
    set_colour(colour, shade({normals[k].x, normals[k].y, 0}));
    glVertex3d(a.x, a.y, z0);
    glVertex3d(b.x, b.y, z0);
    glVertex3d(b.x, b.y, z1);
    glVertex3d(a.x, a.y, z1);
  }
}

// An unlit upright square facing `facing` (its normal), centred at (c, z), `across` wide and
// `tall` high. Inside the caller's glBegin(GL_QUADS).
void upright_quad(Vec2 c, double z, double facing, double across, double tall, Rgb colour) {
  const Vec2 side = Vec2{-std::sin(facing), std::cos(facing)} * (0.5 * across);
  set_colour(colour);
  glVertex3d(c.x - side.x, c.y - side.y, z - 0.5 * tall);
  glVertex3d(c.x + side.x, c.y + side.y, z - 0.5 * tall);
  glVertex3d(c.x + side.x, c.y + side.y, z + 0.5 * tall);
  glVertex3d(c.x - side.x, c.y - side.y, z + 0.5 * tall);
}

const Rgb kLampOn[3] = {{1.0f, 0.05f, 0.02f}, {1.0f, 0.78f, 0.0f}, {0.1f, 1.0f, 0.25f}};
const Rgb kLampOff{0.13f, 0.13f, 0.12f};
const Rgb kHead{0.07f, 0.07f, 0.07f}, kPole{0.28f, 0.28f, 0.28f};
const Rgb kBrakeOn{1.0f, 0.08f, 0.05f}, kBrakeOff{0.32f, 0.03f, 0.03f};

}  // namespace

CameraRenderer::CameraRenderer(const RoadMap& map, CameraConfig cfg)
    : cfg_(std::move(cfg)), weather_(nullptr) {
  check_camera_config(cfg_);
  weather_ = &episode_weather(cfg_.weather, 0);
  gl_ = std::make_unique<GlContext>(cfg_.width, cfg_.height);
  build_static(map);
}

CameraRenderer::~CameraRenderer() {
  gl_->make_current();
  if (ground_list_ != 0) glDeleteLists(ground_list_, 1);
  for (const auto& layer : layers_)
    for (const Cell& cell : layer) glDeleteLists(cell.list, 1);
}

void CameraRenderer::set_weather(const CameraWeather& weather) { weather_ = &weather; }

// The display lists hold geometry only: render() sets each layer's colour from the weather of
// the frame before calling them, so a change of weather rebuilds nothing.
void CameraRenderer::build_static(const RoadMap& map) {
  // The ground, far beyond the map's lanes.
  Vec2 lo = map.min, hi = map.max;
  if (lo.x > hi.x || lo.y > hi.y) lo = hi = Vec2{};
  const double m = 2.0 * cfg_.far_m;
  ground_list_ = glGenLists(1);
  glNewList(ground_list_, GL_COMPILE);
  glBegin(GL_QUADS);
  glVertex3d(lo.x - m, lo.y - m, 0.0);
  glVertex3d(hi.x + m, lo.y - m, 0.0);
  glVertex3d(hi.x + m, hi.y + m, 0.0);
  glVertex3d(lo.x - m, hi.y + m, 0.0);
  glEnd();
  glEndList();

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
  // In this order (render() reads layers 0-1 as surfaces, 2-3 as paint; layer_colours gives
  // their colours).
  for (const FlatLayer* layer : {&sidewalks, &roads, &paint, &kerbs}) {
    std::vector<Cell>& cells = layers_.emplace_back();
    for (const auto& [key, corners] : layer->cells) {
      Cell cell;
      cell.lo = cell.hi = corners.front();
      cell.list = glGenLists(1);
      glNewList(cell.list, GL_COMPILE);
      glBegin(GL_QUADS);
      for (const Vec2& p : corners) {
        cell.lo = {std::min(cell.lo.x, p.x), std::min(cell.lo.y, p.y)};
        cell.hi = {std::max(cell.hi.x, p.x), std::max(cell.hi.y, p.y)};
        glVertex3d(p.x, p.y, 0.0);
      }
      glEnd();
      glEndList();
      cells.push_back(cell);
    }
  }
}

void CameraRenderer::render(const CameraScene& scene, uint8_t* out) {
  gl_->make_current();
  const CameraWeather& w = *weather_;
  const CameraFrame f = camera_frame(cfg_, scene.ego);
  glViewport(0, 0, cfg_.width, cfg_.height);
  glDisable(GL_LIGHTING);
  glDisable(GL_CULL_FACE);
  glDisable(GL_DITHER);
  glDisable(GL_BLEND);
  glShadeModel(GL_FLAT);
  glClearColor(w.sky[0], w.sky[1], w.sky[2], 1.0f);
  glClearDepth(1.0);
  glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);

  // The projection of sense/camera.hpp's pixel convention: window x = col, window y = H - row.
  const double n = cfg_.near_m, k = n / f.focal;
  glMatrixMode(GL_PROJECTION);
  glLoadIdentity();
  glFrustum(-f.cx * k, (cfg_.width - f.cx) * k, -(cfg_.height - f.cy) * k, f.cy * k, n, cfg_.far_m);
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

  // The flat layers in painter's order, then the solids with depth.
  glDisable(GL_DEPTH_TEST);
  set_colour(rgb(w.ground));
  glCallList(ground_list_);
  const double half_fov = 0.5 * cfg_.hfov_deg * M_PI / 180.0 + 0.1;
  const Rgb layer_colours[] = {rgb(w.sidewalk), rgb(w.road), rgb(w.marking), rgb(w.kerb)};
  for (size_t k = 0; k < layers_.size(); ++k) {
    const double reach = k < 2 ? kSurfaceDrawDistance : kPaintDrawDistance;
    set_colour(layer_colours[k]);
    for (const Cell& cell : layers_[k])
      if (in_view(f, half_fov, cell.lo, cell.hi, reach)) glCallList(cell.list);
  }
  glEnable(GL_DEPTH_TEST);
  glDepthFunc(GL_LESS);
  // The solids in one batch, each left out when it cannot be in view.
  auto visible = [&](Vec2 c, double r) {
    return in_view(f, half_fov, c - Vec2{r, r}, c + Vec2{r, r}, cfg_.far_m);
  };
  glBegin(GL_QUADS);
  for (const CameraScene::Vehicle& v : scene.vehicles) {
    const Box& b = v.box;
    if (!visible(b.center, 0.5 * (b.length + b.width))) continue;
    solid_box(b.center, b.heading, b.length, b.width, 0.0, v.height, from_hex(v.colour), w);
    // Brake lights on the rear face, just behind it.
    const Vec2 u{std::cos(b.heading), std::sin(b.heading)}, side{-u.y, u.x};
    const Vec2 rear = b.center - u * (0.5 * b.length + 0.02);
    const double lateral = std::max(0.0, 0.5 * b.width - 0.25);
    for (double s : {1.0, -1.0})
      upright_quad(rear + side * (s * lateral), 0.85, b.heading + M_PI, 0.25, 0.18,
                   v.braking ? kBrakeOn : kBrakeOff);
  }
  for (const CameraScene::Pedestrian& ped : scene.pedestrians)
    if (visible(ped.box.center, ped.box.length + ped.box.width))
      solid_box(ped.box.center, ped.box.heading, ped.box.length, ped.box.width, 0.0, ped.height,
                from_hex(ped.colour), w);
  const LightHeadGeometry& g = kLightHead;
  for (const CameraScene::Light& l : scene.lights) {
    if (!visible(l.position, 1.0)) continue;
    solid_box(l.position, l.facing, 0.12, 0.12, 0.0, g.pole_height, kPole, w);
    solid_box(l.position, l.facing, g.head_depth, g.head_width, g.pole_height,
              g.pole_height + g.head_height, kHead, w);
    const int lit = l.state == 'r' ? 0 : l.state == 'y' ? 1 : 2;
    const Vec2 face = l.position + Vec2{std::cos(l.facing), std::sin(l.facing)} *
                                       (0.5 * g.head_depth + 0.01);
    for (int lamp = 0; lamp < 3; ++lamp)
      upright_quad(face, g.lamp_centre_height(lamp), l.facing, g.lamp_size, g.lamp_size,
                   lamp == lit ? kLampOn[lamp] : kLampOff);
  }
  glEnd();
  gl_->read_rgb_planes(out);
}

}  // namespace cd
