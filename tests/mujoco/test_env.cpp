// MuJoCo-Image environments (src/mujoco/env*): Gym's rewards recomputed by hand from the
// recorded state, every termination rule, seeded resets, frames.
// needs: mujoco
#include <gtest/gtest.h>
#include <mujoco/mujoco.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <set>
#include <string>
#include <vector>

#include "../support/test_support.hpp"
#include "core/error.hpp"
#include "mujoco/env.hpp"

namespace cd::mj {
namespace {

double sum_sq(const std::vector<double>& a) {
  double s = 0;
  for (double v : a) s += v * v;
  return s;
}

// A deterministic, varied action sequence inside [-scale, scale].
std::vector<double> scripted_action(int t, int dim, double scale = 1.0) {
  std::vector<double> a(dim);
  for (int j = 0; j < dim; ++j) a[j] = scale * std::sin(0.7 * t + 1.3 * j);
  return a;
}

bool has_newline(const std::string& s) { return s.find('\n') != std::string::npos; }

// ---------------------------------------------------------------- errors, shapes

TEST(MujocoEnv, UnknownEnvIsOneLineConfigError) {
  try {
    Env env("walker2d-typo");
    FAIL() << "an unknown env must throw";
  } catch (const ConfigError& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find("unknown MuJoCo environment 'walker2d-typo'"), std::string::npos) << msg;
    EXPECT_NE(msg.find("hopper"), std::string::npos) << "should list the known envs: " << msg;
    EXPECT_FALSE(has_newline(msg));
  }
}

TEST(MujocoEnv, MissingModelFileIsOneLineConfigError) {
  test::TempDir dir("cdtest-mj");
  EnvOptions o;
  o.assets_dir = dir.path();
  try {
    Env env("hopper", o);
    FAIL() << "a missing model file must throw";
  } catch (const ConfigError& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find(dir / "hopper.xml"), std::string::npos) << msg;
    EXPECT_NE(msg.find("not found"), std::string::npos) << msg;
    EXPECT_FALSE(has_newline(msg));
  }
}

TEST(MujocoEnv, InvalidModelFileIsOneLineSimError) {
  test::TempDir dir("cdtest-mj");
  test::write_text(dir / "reacher.xml", "<mujoco><worldbody><body><geom type=\"nope\"/></body>\n"
                                        "</worldbody></mujoco>\n");
  EnvOptions o;
  o.assets_dir = dir.path();
  try {
    Env env("reacher", o);
    FAIL() << "an invalid model must throw";
  } catch (const SimError& e) {
    EXPECT_NE(std::string(e.what()).find(dir / "reacher.xml"), std::string::npos) << e.what();
    EXPECT_FALSE(has_newline(e.what())) << e.what();
  }
}

TEST(MujocoEnv, ShapesStepsAndBoundsAreGyms) {
  struct Expect {
    const char* name;
    int nq, nv, nu;
    double dt, bound;
    int limit;
  };
  const Expect table[] = {{"halfcheetah", 9, 9, 6, 0.05, 1.0, 1000},
                          {"hopper", 6, 6, 3, 0.008, 1.0, 1000},
                          {"ant", 15, 14, 8, 0.05, 1.0, 1000},
                          {"reacher", 4, 4, 2, 0.02, 1.0, 50},
                          {"humanoid", 24, 23, 17, 0.015, 0.4, 1000}};
  for (const Expect& x : table) {
    Env env(x.name);
    EXPECT_EQ(env.qpos_dim(), x.nq) << x.name;
    EXPECT_EQ(env.state_dim(), x.nq + x.nv) << x.name;
    EXPECT_EQ(env.action_dim(), x.nu) << x.name;
    EXPECT_NEAR(env.dt(), x.dt, 1e-12) << x.name;
    EXPECT_EQ(env.max_steps(), x.limit) << x.name;
    for (double v : env.action_low()) EXPECT_DOUBLE_EQ(v, -x.bound) << x.name;
    for (double v : env.action_high()) EXPECT_DOUBLE_EQ(v, x.bound) << x.name;
  }
}

TEST(MujocoEnv, WrongActionSizeIsOneLineSimError) {
  Env env("reacher");
  env.reset(0);
  std::vector<double> a(3, 0.0);
  EXPECT_THROW(env.step(a), SimError);
  std::vector<double> nan(2, std::numeric_limits<double>::quiet_NaN());
  EXPECT_THROW(env.step(nan), SimError);
}

// ---------------------------------------------------------------- seeded resets

TEST(MujocoEnv, SameSeedSameStateAndFrameBytes) {
  for (const std::string& name : env_names()) {
    Env a(name), b(name);
    const Frame fa = a.reset(42), fb = b.reset(42);
    EXPECT_EQ(a.state(), b.state()) << name;
    EXPECT_EQ(fa, fb) << name;
    const std::vector<double> act = scripted_action(3, a.action_dim(), 0.3);
    a.step(act);
    b.step(act);
    EXPECT_EQ(a.state(), b.state()) << name;
    EXPECT_EQ(a.render(), b.render()) << name;
    Env c(name);
    c.reset(43);
    EXPECT_NE(a.reset(42), Frame()) << name;
    EXPECT_NE(a.state(), c.state()) << name << ": another seed, another start";
  }
}

TEST(MujocoEnv, ResetNoiseHasGymsScales) {
  // Uniform noise scales on qpos (and qvel where Gym draws it uniformly).
  const struct {
    const char* name;
    double qpos_scale, qvel_uniform_scale;  // qvel_uniform_scale 0: normal noise
  } table[] = {{"hopper", 5e-3, 5e-3}, {"humanoid", 1e-2, 1e-2}, {"halfcheetah", 0.1, 0},
               {"ant", 0.1, 0}};
  for (const auto& x : table) {
    Env env(x.name);
    env.reset(5);
    const std::vector<double> s = env.state();
    const mjModel& m = env.model();
    double max_q = 0;
    for (int i = 0; i < m.nq; ++i) max_q = std::max(max_q, std::abs(s[i] - m.qpos0[i]));
    EXPECT_LE(max_q, x.qpos_scale) << x.name;
    EXPECT_GT(max_q, x.qpos_scale / 10) << x.name << ": the noise should be drawn";
    if (x.qvel_uniform_scale > 0) {
      for (int i = 0; i < m.nv; ++i) EXPECT_LE(std::abs(s[m.nq + i]), x.qvel_uniform_scale);
    }
  }
  // Reacher: the goal inside the 0.2 disc, its velocity zero, the arm near qpos0.
  Env reacher("reacher");
  for (uint64_t seed = 0; seed < 20; ++seed) {
    reacher.reset(seed);
    const std::vector<double> s = reacher.state();
    EXPECT_LT(std::hypot(s[2], s[3]), 0.2);
    EXPECT_LE(std::abs(s[0]), 0.1);
    EXPECT_LE(std::abs(s[1]), 0.1);
    EXPECT_EQ(s[6], 0.0);
    EXPECT_EQ(s[7], 0.0);
    EXPECT_LE(std::abs(s[4]), 0.005);
  }
}

TEST(MujocoEnv, SetStateRestoresTheTrajectory) {
  Env env("hopper"), copy("hopper");
  env.reset(1);
  copy.reset(2);
  copy.set_state(env.state());
  EXPECT_EQ(copy.state(), env.state());
  for (int t = 0; t < 5; ++t) {
    const auto a = scripted_action(t, 3);
    const StepResult r1 = env.step(a), r2 = copy.step(a);
    EXPECT_NEAR(r1.reward, r2.reward, 1e-9);
  }
  const auto s1 = env.state(), s2 = copy.state();
  for (size_t i = 0; i < s1.size(); ++i) EXPECT_NEAR(s1[i], s2[i], 1e-6);
}

// ---------------------------------------------------------------- rewards by hand

TEST(MujocoReward, HalfCheetahIsForwardVelocityMinusControlCost) {
  Env env("halfcheetah");
  env.reset(3);
  for (int t = 0; t < 30; ++t) {
    const double x0 = env.state()[0];
    const auto a = scripted_action(t, 6);
    const StepResult r = env.step(a);
    const double x1 = env.state()[0];
    EXPECT_NEAR(r.reward, (x1 - x0) / 0.05 - 0.1 * sum_sq(a), 1e-9) << "step " << t;
    EXPECT_FALSE(r.terminated);
  }
}

TEST(MujocoReward, HopperIsVelocityPlusHealthyMinusControlCost) {
  Env env("hopper");
  env.reset(3);
  for (int t = 0; t < 20; ++t) {
    const double x0 = env.state()[0];
    const auto a = scripted_action(t, 3, 0.5);
    const StepResult r = env.step(a);
    const double x1 = env.state()[0];
    EXPECT_NEAR(r.reward, (x1 - x0) / 0.008 + 1.0 - 1e-3 * sum_sq(a), 1e-9) << "step " << t;
    if (r.terminated) break;
  }
}

TEST(MujocoReward, AntIsVelocityPlusHealthyMinusControlAndContactCost) {
  Env env("ant");
  env.reset(3);
  bool saw_contact = false;
  for (int t = 0; t < 30; ++t) {
    const double x0 = env.state()[0];  // the free joint's x is the torso's
    const auto a = scripted_action(t, 8, 0.8);
    const StepResult r = env.step(a);
    const double x1 = env.state()[0];
    const mjData& d = env.data();
    double contact = 0;
    for (int i = 0; i < 6 * env.model().nbody; ++i) {
      const double f = std::clamp<double>(d.cfrc_ext[i], -1, 1);
      contact += f * f;
    }
    saw_contact = saw_contact || contact > 0;
    EXPECT_NEAR(r.reward, (x1 - x0) / 0.05 + 1.0 - 0.5 * sum_sq(a) - 5e-4 * contact, 1e-9)
        << "step " << t;
    if (r.terminated) break;
  }
  EXPECT_TRUE(saw_contact) << "the feet touch the floor: cfrc_ext must be computed";
}

TEST(MujocoReward, ReacherIsMinusDistanceBeforeTheStepMinusControlCost) {
  Env env("reacher");
  env.reset(3);
  for (int t = 0; t < 50; ++t) {
    // The fingertip from the joint angles: links of 0.1 m, tip 0.11 m past the elbow.
    const std::vector<double> s = env.state();
    const double tip_x = 0.1 * std::cos(s[0]) + 0.11 * std::cos(s[0] + s[1]);
    const double tip_y = 0.1 * std::sin(s[0]) + 0.11 * std::sin(s[0] + s[1]);
    const double dist = std::hypot(tip_x - s[2], tip_y - s[3]);
    const auto a = scripted_action(t, 2);
    const StepResult r = env.step(a);
    EXPECT_NEAR(r.reward, -dist - sum_sq(a), 1e-9) << "step " << t;
    EXPECT_FALSE(r.terminated);
    EXPECT_EQ(r.truncated, t == 49) << "step " << t;
  }
}

TEST(MujocoReward, HumanoidIsComVelocityPlusHealthyMinusCosts) {
  Env env("humanoid");
  env.reset(3);
  auto com_x = [&] {
    const mjModel& m = env.model();
    const mjData& d = env.data();
    double mass = 0, x = 0;
    for (int i = 0; i < m.nbody; ++i) {
      mass += m.body_mass[i];
      x += m.body_mass[i] * d.xipos[3 * i];
    }
    return x / mass;
  };
  for (int t = 0; t < 20; ++t) {
    const double c0 = com_x();
    const auto a = scripted_action(t, 17, 0.4);
    const StepResult r = env.step(a);
    const double c1 = com_x();
    double contact = 0;
    for (int i = 0; i < 6 * env.model().nbody; ++i)
      contact += env.data().cfrc_ext[i] * env.data().cfrc_ext[i];
    const double expected =
        1.25 * (c1 - c0) / 0.015 + 5.0 - 0.1 * sum_sq(a) - std::min(5e-7 * contact, 10.0);
    EXPECT_NEAR(r.reward, expected, 1e-9) << "step " << t;
    if (r.terminated) break;
  }
}

// ---------------------------------------------------------------- terminations

// The spec's health test on a state set by hand.
bool healthy_at(Env& env, std::vector<double> state) {
  env.set_state(state);
  return env.spec().healthy(env.model(), env.data());
}

TEST(MujocoTermination, HopperRules) {
  Env env("hopper");
  env.reset(0);
  const std::vector<double> ok = env.state();
  ASSERT_TRUE(healthy_at(env, ok));
  auto with = [&](int i, double v) {
    std::vector<double> s = ok;
    s[i] = v;
    return s;
  };
  EXPECT_FALSE(healthy_at(env, with(1, 0.7))) << "z must be above 0.7";
  EXPECT_TRUE(healthy_at(env, with(1, 0.71)));
  EXPECT_FALSE(healthy_at(env, with(2, 0.2))) << "|angle| must be below 0.2";
  EXPECT_FALSE(healthy_at(env, with(2, -0.2)));
  EXPECT_TRUE(healthy_at(env, with(2, 0.19)));
  EXPECT_FALSE(healthy_at(env, with(8, 100.0))) << "state[2:] must be inside (-100, 100)";
  EXPECT_TRUE(healthy_at(env, with(8, 99.0)));
  EXPECT_TRUE(healthy_at(env, with(0, 500.0))) << "rootx is not part of the check";
  EXPECT_FALSE(healthy_at(env, with(3, std::numeric_limits<double>::quiet_NaN())));
}

TEST(MujocoTermination, HopperFallsOverUnderAScriptedAction) {
  Env env("hopper");
  env.reset(0);
  const std::vector<double> bend = {-1.0, 0.0, 0.0};  // thigh pulled: it tips over
  int steps = 0;
  StepResult r;
  while (steps < 300 && !(r = env.step(bend)).terminated) ++steps;
  ASSERT_TRUE(r.terminated) << "the hopper should fall within 300 steps";
  const std::vector<double> s = env.state();
  EXPECT_TRUE(s[1] <= 0.7 || std::abs(s[2]) >= 0.2) << "z " << s[1] << " angle " << s[2];
  EXPECT_FALSE(r.truncated);
}

TEST(MujocoTermination, AntZRange) {
  Env env("ant");
  env.reset(0);
  std::vector<double> s = env.state();
  auto z = [&](double v) {
    s[2] = v;
    return healthy_at(env, s);
  };
  EXPECT_FALSE(z(0.19));
  EXPECT_TRUE(z(0.2));
  EXPECT_TRUE(z(1.0));
  EXPECT_FALSE(z(1.01));
  EXPECT_FALSE(z(std::numeric_limits<double>::infinity()));
}

TEST(MujocoTermination, HumanoidZRangeAndFall) {
  Env env("humanoid");
  env.reset(0);
  std::vector<double> s = env.state();
  auto z = [&](double v) {
    s[2] = v;
    return healthy_at(env, s);
  };
  EXPECT_FALSE(z(1.0));
  EXPECT_TRUE(z(1.01));
  EXPECT_TRUE(z(1.99));
  EXPECT_FALSE(z(2.0));
  env.reset(0);
  const std::vector<double> zero(17, 0.0);
  int steps = 0;
  StepResult r;
  while (steps < 200 && !(r = env.step(zero)).terminated) ++steps;
  EXPECT_TRUE(r.terminated) << "with no control the humanoid falls";
  EXPECT_LE(env.state()[2], 1.0);
}

TEST(MujocoTermination, CheetahAndReacherOnlyTruncate) {
  EXPECT_EQ(env_spec("halfcheetah").healthy, nullptr);
  EXPECT_EQ(env_spec("reacher").healthy, nullptr);
  Env env("halfcheetah");
  env.reset(0);
  StepResult r;
  for (int t = 0; t < 1000; ++t) {
    r = env.step(scripted_action(t, 6));
    ASSERT_FALSE(r.terminated);
    ASSERT_EQ(r.truncated, t == 999) << "step " << t;
  }
}

// ---------------------------------------------------------------- frames

size_t differing_bytes(const Frame& a, const Frame& b) {
  size_t n = 0;
  for (size_t i = 0; i < a.size(); ++i) n += a[i] != b[i];
  return n;
}

TEST(MujocoRender, FramesAreNotBlankAndFollowThePose) {
  // One joint moved by hand per env: the frame must change where the body is drawn.
  const struct {
    const char* name;
    int qpos_index;
    double delta;
  } table[] = {{"halfcheetah", 3, 0.8}, {"hopper", 3, -1.0}, {"ant", 7, 0.5},
               {"reacher", 0, 1.5}, {"humanoid", 14, 0.8}};
  for (const auto& x : table) {
    Env env(x.name);
    const Frame first = env.reset(0);
    ASSERT_EQ(first.size(), 3u * 64 * 64) << x.name;
    const std::set<uint8_t> values(first.begin(), first.end());
    EXPECT_GT(values.size(), 20u) << x.name << ": a blank or flat frame";
    std::vector<double> s = env.state();
    s[x.qpos_index] += x.delta;
    env.set_state(s);
    const Frame moved = env.render();
    EXPECT_GT(differing_bytes(first, moved), 40u) << x.name << ": the pose change must show";
  }
}

TEST(MujocoRender, FrameSizeIsConfigurable) {
  EnvOptions o;
  o.width = 48;
  o.height = 32;
  Env env("hopper", o);
  const Frame f = env.reset(0);
  EXPECT_EQ(f.size(), 3u * 48 * 32);
  EXPECT_EQ(env.frame_bytes(), f.size());
  const std::set<uint8_t> values(f.begin(), f.end());
  EXPECT_GT(values.size(), 20u);
  o.width = 0;
  EXPECT_THROW(Env("hopper", o), ConfigError);
}

}  // namespace
}  // namespace cd::mj
