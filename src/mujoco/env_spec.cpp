#include "mujoco/env_spec.hpp"

#include <mujoco/mujoco.h>

#include <algorithm>
#include <cmath>

#include "core/error.hpp"

namespace cd::mj {

namespace {

double squared_norm(std::span<const double> a) {
  double s = 0;
  for (double v : a) s += v * v;
  return s;
}

int body_id(const mjModel& m, const char* name) {
  const int id = mj_name2id(&m, mjOBJ_BODY, name);
  if (id < 0) throw SimError(std::string("MuJoCo model lacks body '") + name + "'");
  return id;
}

bool all_finite(const mjModel& m, const mjData& d) {
  for (int i = 0; i < m.nq; ++i)
    if (!std::isfinite(d.qpos[i])) return false;
  for (int i = 0; i < m.nv; ++i)
    if (!std::isfinite(d.qvel[i])) return false;
  return true;
}

void add_uniform(mjtNum* x, int n, double scale, Rng& rng) {
  for (int i = 0; i < n; ++i) x[i] += rng.uniform(-scale, scale);
}

void add_normal(mjtNum* x, int n, double scale, Rng& rng) {
  for (int i = 0; i < n; ++i) x[i] += scale * standard_normal(rng);
}

// ---------------------------------------------------------------- halfcheetah (v3)

double root_x(const mjModel&, const mjData& d) { return d.qpos[0]; }

double cheetah_reward(const mjModel&, const mjData& d, double before, std::span<const double> a,
                      double dt) {
  return (d.qpos[0] - before) / dt - 0.1 * squared_norm(a);
}

void cheetah_reset(const mjModel& m, mjData& d, Rng& rng) {
  add_uniform(d.qpos, m.nq, 0.1, rng);
  add_normal(d.qvel, m.nv, 0.1, rng);
}

// ---------------------------------------------------------------- hopper (v3)

double hopper_reward(const mjModel&, const mjData& d, double before, std::span<const double> a,
                     double dt) {
  return (d.qpos[0] - before) / dt + 1.0 - 1e-3 * squared_norm(a);
}

bool hopper_healthy(const mjModel& m, const mjData& d) {
  // state_vector()[2:]: qpos without rootx and rootz, then qvel; all strictly inside (-100, 100).
  for (int i = 2; i < m.nq; ++i)
    if (!(d.qpos[i] > -100.0 && d.qpos[i] < 100.0)) return false;
  for (int i = 0; i < m.nv; ++i)
    if (!(d.qvel[i] > -100.0 && d.qvel[i] < 100.0)) return false;
  const double z = d.qpos[1], angle = d.qpos[2];
  return z > 0.7 && angle > -0.2 && angle < 0.2;
}

void hopper_reset(const mjModel& m, mjData& d, Rng& rng) {
  add_uniform(d.qpos, m.nq, 5e-3, rng);
  add_uniform(d.qvel, m.nv, 5e-3, rng);
}

// ---------------------------------------------------------------- ant (v3)

double torso_x(const mjModel& m, const mjData& d) { return d.xpos[3 * body_id(m, "torso")]; }

double ant_reward(const mjModel& m, const mjData& d, double before, std::span<const double> a,
                  double dt) {
  double contact = 0;
  for (int i = 0; i < 6 * m.nbody; ++i) {
    const double f = std::clamp<double>(d.cfrc_ext[i], -1.0, 1.0);
    contact += f * f;
  }
  return (torso_x(m, d) - before) / dt + 1.0 - 0.5 * squared_norm(a) - 5e-4 * contact;
}

bool ant_healthy(const mjModel& m, const mjData& d) {
  return all_finite(m, d) && d.qpos[2] >= 0.2 && d.qpos[2] <= 1.0;
}

void ant_reset(const mjModel& m, mjData& d, Rng& rng) {
  add_uniform(d.qpos, m.nq, 0.1, rng);
  add_normal(d.qvel, m.nv, 0.1, rng);
}

// ---------------------------------------------------------------- reacher (v2/v4)

double fingertip_distance(const mjModel& m, const mjData& d) {
  const mjtNum* tip = d.xpos + 3 * body_id(m, "fingertip");
  const mjtNum* target = d.xpos + 3 * body_id(m, "target");
  const double dx = tip[0] - target[0], dy = tip[1] - target[1], dz = tip[2] - target[2];
  return std::sqrt(dx * dx + dy * dy + dz * dz);
}

// Gym computes the distance before the physics steps: `before` is it.
double reacher_reward(const mjModel&, const mjData&, double before, std::span<const double> a,
                      double) {
  return -before - squared_norm(a);
}

void reacher_reset(const mjModel& m, mjData& d, Rng& rng) {
  add_uniform(d.qpos, m.nq, 0.1, rng);
  double gx = 0, gy = 0;
  do {
    gx = rng.uniform(-0.2, 0.2);
    gy = rng.uniform(-0.2, 0.2);
  } while (std::sqrt(gx * gx + gy * gy) >= 0.2);
  d.qpos[m.nq - 2] = gx;
  d.qpos[m.nq - 1] = gy;
  add_uniform(d.qvel, m.nv, 0.005, rng);
  d.qvel[m.nv - 2] = 0;
  d.qvel[m.nv - 1] = 0;
}

// ---------------------------------------------------------------- humanoid (v3)

double mass_center_x(const mjModel& m, const mjData& d) {
  double mass = 0, x = 0;
  for (int i = 0; i < m.nbody; ++i) {
    mass += m.body_mass[i];
    x += m.body_mass[i] * d.xipos[3 * i];
  }
  return x / mass;
}

double humanoid_reward(const mjModel& m, const mjData& d, double before, std::span<const double> a,
                       double dt) {
  double contact = 0;
  for (int i = 0; i < 6 * m.nbody; ++i) contact += d.cfrc_ext[i] * d.cfrc_ext[i];
  return 1.25 * (mass_center_x(m, d) - before) / dt + 5.0 - 0.1 * squared_norm(a) -
         std::min(5e-7 * contact, 10.0);
}

bool humanoid_healthy(const mjModel&, const mjData& d) { return d.qpos[2] > 1.0 && d.qpos[2] < 2.0; }

void humanoid_reset(const mjModel& m, mjData& d, Rng& rng) {
  add_uniform(d.qpos, m.nq, 1e-2, rng);
  add_uniform(d.qvel, m.nv, 1e-2, rng);
}

// ---------------------------------------------------------------- the table

std::vector<EnvSpec> make_specs() {
  std::vector<EnvSpec> specs;
  {
    EnvSpec s;
    s.name = "halfcheetah";
    s.position_dims = 1;
    s.model_file = "halfcheetah.xml";
    s.frame_skip = 5;
    s.progress = root_x;
    s.reward = cheetah_reward;
    s.reset_noise = cheetah_reset;
    s.camera.track_body = 1;
    s.camera.distance = 4.0;
    specs.push_back(s);
  }
  {
    EnvSpec s;
    s.name = "hopper";
    s.position_dims = 1;
    s.model_file = "hopper.xml";
    s.frame_skip = 4;
    s.progress = root_x;
    s.reward = hopper_reward;
    s.healthy = hopper_healthy;
    s.reset_noise = hopper_reset;
    s.camera.track_body = 2;
    s.camera.distance = 3.0;
    s.camera.fixed_height = true;
    s.camera.lookat[2] = 1.15;
    specs.push_back(s);
  }
  {
    EnvSpec s;
    s.name = "ant";
    s.position_dims = 2;
    s.model_file = "ant.xml";
    s.frame_skip = 5;
    s.progress = torso_x;
    s.reward = ant_reward;
    s.healthy = ant_healthy;
    s.reset_noise = ant_reset;
    s.contact_forces = true;
    s.camera.track_body = 1;
    s.camera.distance = 4.0;
    s.camera.elevation = -30.0;  // Gym gives only the distance; from above, the legs show
    specs.push_back(s);
  }
  {
    EnvSpec s;
    s.name = "reacher";
    s.model_file = "reacher.xml";
    s.frame_skip = 2;
    s.max_steps = 50;
    s.progress = fingertip_distance;
    s.reward = reacher_reward;
    s.reset_noise = reacher_reset;
    // Gym's is a fixed camera on the world; ours looks straight down on the arena so that
    // 64x64 pixels show both the arm and the target.
    s.camera.track_body = -1;
    s.camera.distance = 0.85;
    s.camera.elevation = -90.0;
    specs.push_back(s);
  }
  {
    EnvSpec s;
    s.name = "humanoid";
    s.position_dims = 2;
    s.model_file = "humanoid.xml";
    s.frame_skip = 5;
    s.progress = mass_center_x;
    s.reward = humanoid_reward;
    s.healthy = humanoid_healthy;
    s.reset_noise = humanoid_reset;
    s.contact_forces = true;
    s.camera.track_body = 1;
    s.camera.distance = 4.0;
    s.camera.fixed_height = true;
    s.camera.lookat[2] = 2.0;
    specs.push_back(s);
  }
  return specs;
}

const std::vector<EnvSpec>& specs() {
  static const std::vector<EnvSpec> all = make_specs();
  return all;
}

}  // namespace

const EnvSpec& env_spec(const std::string& name) {
  for (const EnvSpec& s : specs())
    if (s.name == name) return s;
  std::string known;
  for (const EnvSpec& s : specs()) known += (known.empty() ? "" : ", ") + s.name;
  throw ConfigError("unknown MuJoCo environment '" + name + "' (known: " + known + ")");
}

std::vector<std::string> env_names() {
  std::vector<std::string> names;
  for (const EnvSpec& s : specs()) names.push_back(s.name);
  return names;
}

}  // namespace cd::mj
