// The front camera's GL side (sense/camera.hpp): the town's flat layers in one display list,
// drawn in painter's order without depth, then the boxes of vehicles, pedestrians and signal
// heads with depth. Faces are shaded on the CPU (ambient + the sun's diffuse share, flat per
// face) and lamps and brake lights are unlit colours, so GL's lighting state plays no part.
#include <GL/gl.h>

#include <cmath>

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
constexpr double kDashPiece = 0.5;  // dashed lines are drawn in pieces this long (m)

// A flat band along `pts` between the offsets `left` and `right` (metres to the left; right <
// left), on the ground.
void band(const Polyline& pts, double left, double right) {
  if (pts.size() < 2) return;
  const Polyline l = offset_polyline(pts, left), r = offset_polyline(pts, right);
  glBegin(GL_QUAD_STRIP);
  for (size_t i = 0; i < pts.size(); ++i) {
    glVertex3d(l[i].x, l[i].y, 0.0);
    glVertex3d(r[i].x, r[i].y, 0.0);
  }
  glEnd();
}

// The dashed version of a band `width` wide centred on `pts`, in the dash pattern of the
// bird's-eye view (dash_painted along each segment's direction).
void dashed_band(const Polyline& pts, double width, double dash, double gap) {
  glBegin(GL_QUADS);
  for (size_t i = 1; i < pts.size(); ++i) {
    const Vec2 a = pts[i - 1], ab = pts[i] - a;
    const double len = ab.norm();
    if (len <= 0) continue;
    const Vec2 d = ab * (1.0 / len), n = Vec2{-d.y, d.x} * (0.5 * width);
    for (double s0 = 0; s0 < len; s0 += kDashPiece) {
      const double s1 = std::min(len, s0 + kDashPiece);
      if (!dash_painted((a + d * (0.5 * (s0 + s1))).dot(d), dash, dash + gap)) continue;
      const Vec2 p0 = a + d * s0, p1 = a + d * s1;
      glVertex3d(p0.x + n.x, p0.y + n.y, 0.0);
      glVertex3d(p1.x + n.x, p1.y + n.y, 0.0);
      glVertex3d(p1.x - n.x, p1.y - n.y, 0.0);
      glVertex3d(p0.x - n.x, p0.y - n.y, 0.0);
    }
  }
  glEnd();
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
  glBegin(GL_QUADS);
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
  glEnd();
}

// An unlit upright square facing `facing` (its normal), centred at (c, z), `across` wide and
// `tall` high.
void upright_quad(Vec2 c, double z, double facing, double across, double tall, Rgb colour) {
  const Vec2 side = Vec2{-std::sin(facing), std::cos(facing)} * (0.5 * across);
  set_colour(colour);
  glBegin(GL_QUADS);
  glVertex3d(c.x - side.x, c.y - side.y, z - 0.5 * tall);
  glVertex3d(c.x + side.x, c.y + side.y, z - 0.5 * tall);
  glVertex3d(c.x + side.x, c.y + side.y, z + 0.5 * tall);
  glVertex3d(c.x - side.x, c.y - side.y, z + 0.5 * tall);
  glEnd();
}

const Rgb kLampOn[3] = {{1.0f, 0.05f, 0.02f}, {1.0f, 0.78f, 0.0f}, {0.1f, 1.0f, 0.25f}};
const Rgb kLampOff{0.13f, 0.13f, 0.12f};
const Rgb kHead{0.07f, 0.07f, 0.07f}, kPole{0.28f, 0.28f, 0.28f};
const Rgb kBrakeOn{1.0f, 0.08f, 0.05f}, kBrakeOff{0.32f, 0.03f, 0.03f};

}  // namespace

CameraRenderer::CameraRenderer(const RoadMap& map, CameraConfig cfg)
    : cfg_(std::move(cfg)), weather_(nullptr) {
  check_camera_config(cfg_);
  weather_ = &camera_weather(cfg_.weather);
  gl_ = std::make_unique<GlContext>(cfg_.width, cfg_.height);
  build_static(map);
}

CameraRenderer::~CameraRenderer() {
  gl_->make_current();
  if (static_list_ != 0) glDeleteLists(static_list_, 1);
}

void CameraRenderer::build_static(const RoadMap& map) {
  const CameraWeather& w = *weather_;
  static_list_ = glGenLists(1);
  glNewList(static_list_, GL_COMPILE);
  // The ground, far beyond the map's lanes.
  Vec2 lo = map.min, hi = map.max;
  if (lo.x > hi.x || lo.y > hi.y) lo = hi = Vec2{};
  const double m = 2.0 * cfg_.far_m;
  set_colour(rgb(w.ground));
  glBegin(GL_QUADS);
  glVertex3d(lo.x - m, lo.y - m, 0.0);
  glVertex3d(hi.x + m, lo.y - m, 0.0);
  glVertex3d(hi.x + m, hi.y + m, 0.0);
  glVertex3d(lo.x - m, hi.y + m, 0.0);
  glEnd();
  // Sidewalks and walking areas, then the roads over them, then what is painted on the roads.
  set_colour(rgb(w.sidewalk));
  for (const LaneGeom& lane : map.lanes)
    if (lane.kind == LaneKind::Sidewalk || lane.kind == LaneKind::WalkingArea)
      band(without_repeats(lane.shape), lane.width / 2, -lane.width / 2);
  set_colour(rgb(w.road));
  for (const LaneGeom& lane : map.lanes)
    if (lane.kind == LaneKind::Driving)
      band(without_repeats(lane.shape), lane.width / 2, -lane.width / 2);
  set_colour(rgb(w.marking));
  for (const LaneGeom& lane : map.lanes) {
    const Polyline pts = without_repeats(lane.shape);
    if (pts.size() < 2) continue;
    if (lane.kind == LaneKind::Crossing) {  // zebra stripes across the crossing's length
      dashed_band(pts, lane.width, 0.5, 0.5);
      continue;
    }
    if (lane.kind != LaneKind::Driving || lane.internal) continue;
    // As the bird's-eye view: the left border dashed, the right border solid unless a
    // neighbour lane draws it as its left border.
    dashed_band(offset_polyline(pts, lane.width / 2), kMarkingWidth, kDash, kGap);
    if (!lane.has_right_neighbour)
      band(offset_polyline(pts, -lane.width / 2), 0.5 * kMarkingWidth, -0.5 * kMarkingWidth);
  }
  set_colour(rgb(w.kerb));
  for (const LaneGeom& lane : map.lanes)
    if (lane.kind == LaneKind::Sidewalk) {
      const Polyline pts = without_repeats(lane.shape);
      if (pts.size() < 2) continue;
      for (double side : {1.0, -1.0})
        band(offset_polyline(pts, side * lane.width / 2), 0.5 * kKerbWidth, -0.5 * kKerbWidth);
    }
  glEndList();
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
  glCallList(static_list_);
  glEnable(GL_DEPTH_TEST);
  glDepthFunc(GL_LESS);
  for (const CameraScene::Vehicle& v : scene.vehicles) {
    const Box& b = v.box;
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
    solid_box(ped.box.center, ped.box.heading, ped.box.length, ped.box.width, 0.0, ped.height,
              from_hex(ped.colour), w);
  const LightHeadGeometry& g = kLightHead;
  for (const CameraScene::Light& l : scene.lights) {
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
  gl_->read_rgb_planes(out);
}

}  // namespace cd
