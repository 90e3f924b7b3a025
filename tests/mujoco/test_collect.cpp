// MuJoCo-Image data (src/mujoco/collect, src/data/mujoco_episode) and the planner expert:
// SPEC section 8's file layout read back by us and by h5py, same seed same bytes, resuming,
// noise flags, an expert queryable at any state.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <cmath>
#include <cstdlib>
#include <fstream>
#include <iterator>
#include <string>

#include "../support/test_support.hpp"
#include "core/error.hpp"
#include "data/mujoco_episode.hpp"
#include "app/settings.hpp"
#include "mujoco/collect.hpp"

#ifndef CD_PYTHON
#define CD_PYTHON "/usr/bin/python3"
#endif

namespace cd::mj {
namespace {

// Tiny runs: a few steps of a small planner.
CollectOptions tiny(const std::string& out, const std::string& env = "reacher") {
  CollectOptions o;
  o.env = env;
  o.out = out;
  o.episodes = 2;
  o.seed = 11;
  o.max_steps = 4;
  o.planner.samples = 4;
  o.planner.horizon = 3;
  o.quiet = true;
  return o;
}

std::string read_bytes(const std::string& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

TEST(MujocoCollect, EpisodeFileRoundTrips) {
  CD_NEEDS_MUJOCO();
  test::TempDir dir("cdtest-mj");
  const CollectOptions o = tiny(dir.path(), "hopper");
  const MujocoEpisode e = record_episode(o, 0);
  ASSERT_EQ(e.frames(), 4u);
  EXPECT_EQ(e.outcome, "truncated");
  write_mujoco_episode(dir / "ep.h5", e);
  const MujocoEpisode back = read_mujoco_episode(dir / "ep.h5");
  EXPECT_EQ(back.env, "hopper");
  EXPECT_EQ(back.seed, e.seed);
  EXPECT_DOUBLE_EQ(back.dt, 0.008);
  EXPECT_EQ(back.frame_skip, 4);
  EXPECT_EQ(back.outcome, "truncated");
  EXPECT_EQ(back.channels, 3);
  EXPECT_EQ(back.height, 64);
  EXPECT_EQ(back.width, 64);
  EXPECT_EQ(back.action_dim, 3);
  EXPECT_EQ(back.state_dim, 12);
  EXPECT_EQ(back.obs, e.obs);
  EXPECT_EQ(back.action, e.action);
  EXPECT_EQ(back.state, e.state);
  EXPECT_EQ(back.reward, e.reward);
  EXPECT_EQ(back.noise, e.noise);
  EXPECT_EQ(back.extra, e.extra);
  // The row's state is the state before its action: row 0 is the reset state of the seed.
  Env env("hopper");
  env.reset(e.seed);
  const std::vector<double> s0 = env.state();
  for (size_t i = 0; i < s0.size(); ++i) EXPECT_FLOAT_EQ(back.state[i], static_cast<float>(s0[i]));
}

TEST(MujocoCollect, DrivingReaderAndMujocoReaderRefuseEachOthersFiles) {
  test::TempDir dir("cdtest-mj");
  test::write_text(dir / "junk.h5", "not hdf5");
  EXPECT_THROW(read_mujoco_episode(dir / "junk.h5"), DataError);
  EXPECT_THROW(read_mujoco_episode(dir / "missing.h5"), IoError);
}

TEST(MujocoCollect, H5pyReadsTheDataset) {
  CD_NEEDS_MUJOCO();
  test::TempDir dir("cdtest-mj");
  CollectOptions o = tiny(dir / "data");
  o.episodes = 1;
  const CollectReport r = collect(o);
  ASSERT_EQ(r.episodes, 1);
  // Without noise the executed action is the label: the reward of each row follows from its
  // state and action (reacher: minus the fingertip distance, minus the control cost).
  const std::string script = R"PY(
import sys, json, h5py, numpy as np
f = h5py.File(sys.argv[1], "r")
def check(cond, what):
    if not cond:
        print("h5py check failed:", what, file=sys.stderr); sys.exit(1)
T = f["reward"].shape[0]
check(T == 4, "T")
check(f["obs"].dtype == np.uint8 and f["obs"].shape == (T, 3, 64, 64), "obs")
check(f["action"].dtype == np.float32 and f["action"].shape == (T, 2), "action")
check(f["state"].dtype == np.float32 and f["state"].shape == (T, 8), "state")
check(f["reward"].dtype == np.float32, "reward dtype")
check(f["noise"].shape == (T,) and not f["noise"][:].any(), "noise")
a = f.attrs
check(a["env"] == b"reacher" and a["domain"] == b"mujoco", "env/domain")
check(int(a["format_version"]) == 1 and int(a["frame_skip"]) == 2, "version/frame_skip")
check(abs(float(a["dt"]) - 0.02) < 1e-12, "dt")
check(int(a["frames"]) == T, "frames")
s, act, rew = f["state"][:], f["action"][:], f["reward"][:]
tip = np.stack([0.1*np.cos(s[:,0]) + 0.11*np.cos(s[:,0]+s[:,1]),
                0.1*np.sin(s[:,0]) + 0.11*np.sin(s[:,0]+s[:,1])], 1)
expected = -np.linalg.norm(tip - s[:,2:4], axis=1) - (act.astype(np.float64)**2).sum(1)
check(np.allclose(rew, expected, atol=1e-4), "reward %s vs %s" % (rew, expected))
check(abs(float(a["episode_return"]) - float(rew.astype(np.float64).sum())) < 1e-4, "return")
check(f["obs"][0].std() > 5, "frame not blank")
m = json.load(open(sys.argv[2]))
check(m["env"] == "reacher" and len(m["episodes"]) == 1, "collect.json")
)PY";
  test::write_text(dir / "oracle.py", script);
  const std::string cmd = std::string(CD_PYTHON) + " '" + (dir / "oracle.py") + "' '" +
                          (dir / "data/episode_000000.h5") + "' '" + (dir / "data/collect.json") +
                          "'";
  const int status = std::system(cmd.c_str());
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << cmd;
}

TEST(MujocoCollect, SameSeedSameBytesAndResume) {
  CD_NEEDS_MUJOCO();
  test::TempDir dir("cdtest-mj");
  const CollectReport a = collect(tiny(dir / "a"));
  const CollectReport b = collect(tiny(dir / "b"));
  EXPECT_EQ(a.recorded_now, 2);
  for (const char* name : {"episode_000000.h5", "episode_000001.h5", "collect.json"}) {
    EXPECT_EQ(read_bytes(dir / "a/" + name), read_bytes(dir / "b/" + name)) << name;
  }
  EXPECT_NE(read_bytes(dir / "a/episode_000000.h5"), read_bytes(dir / "a/episode_000001.h5"));
  // A rerun keeps what is there; a removed file is recorded again, identically.
  const std::string kept = read_bytes(dir / "a/episode_000001.h5");
  test::fs::remove(dir / "a/episode_000001.h5");
  const CollectReport again = collect(tiny(dir / "a"));
  EXPECT_EQ(again.recorded_now, 1);
  EXPECT_EQ(read_bytes(dir / "a/episode_000001.h5"), kept);
  EXPECT_EQ(collect(tiny(dir / "a")).recorded_now, 0);
}

TEST(MujocoCollect, NoiseRowsAreFlaggedAndLabelsStayTheExperts) {
  CD_NEEDS_MUJOCO();
  test::TempDir dir("cdtest-mj");
  CollectOptions o = tiny(dir.path());
  o.noise.enabled = true;
  o.noise.rate = 1.0;  // a window starts at once
  o.noise.min_steps = o.noise.max_steps = 2;
  const MujocoEpisode noisy = record_episode(o, 0);
  ASSERT_EQ(noisy.frames(), 4u);
  EXPECT_EQ(noisy.noise, (std::vector<uint8_t>{1, 1, 1, 1}));
  o.noise.enabled = false;
  const MujocoEpisode clean = record_episode(o, 0);
  EXPECT_EQ(clean.noise, (std::vector<uint8_t>{0, 0, 0, 0}));
  // Row 0: same state, same expert query, so the same label; the executed action differed,
  // hence the reward of row 0 and the state of row 1.
  for (int j = 0; j < clean.action_dim; ++j) EXPECT_EQ(noisy.action[j], clean.action[j]);
  EXPECT_NE(noisy.state[clean.state_dim], clean.state[clean.state_dim]);
}

TEST(MujocoCollect, UnknownEnvAndMissingModelAreOneLineErrors) {
  CD_NEEDS_MUJOCO();
  test::TempDir dir("cdtest-mj");
  CollectOptions o = tiny(dir / "out", "cheetah");
  EXPECT_THROW(collect(o), ConfigError);
  EXPECT_FALSE(test::fs::exists(dir / "out")) << "nothing is written on a config error";
  test::ScopedEnv assets("CAUSALDRIVE_MUJOCO_ASSETS", dir / "no-assets");
  o.env = "ant";
  try {
    collect(o);
    FAIL();
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("ant.xml not found"), std::string::npos) << e.what();
  }
}

TEST(MujocoExpert, QueryableAtAnyStateWithinBoundsAndSeeded) {
  CD_NEEDS_MUJOCO();
  PlannerOptions p;
  p.samples = 8;
  p.horizon = 4;
  p.seed = 3;
  PlannerExpert a("hopper", p), b("hopper", p);
  Env env("hopper");
  env.reset(9);
  std::vector<double> state = env.state();
  state[3] -= 0.3;  // any state, not one from a trajectory of the expert
  const std::vector<double> x = a.act(state), y = b.act(state);
  ASSERT_EQ(x.size(), 3u);
  EXPECT_EQ(x, y) << "same seed, same queries, same actions";
  for (double v : x) EXPECT_TRUE(v >= -1.0 && v <= 1.0) << v;
  EXPECT_EQ(a.simulated_steps(), 8 * 4);
  EXPECT_NE(a.describe().find("mppi samples=8 horizon=4"), std::string::npos) << a.describe();
}

// The [mujoco] planner_* keys are the planner's options (collect, eval's expert and dagger
// read them through planner_options); their defaults leave every env default in place.
TEST(MujocoExpert, PlannerKeysOfTheConfigReachThePlanner) {
  test::TempDir dir("cdtest-mj-planner");
  const std::string path = dir / "p.toml";
  test::write_text(path,
                   "[mujoco]\nplanner_samples = 4\nplanner_horizon = 5\nplanner_iterations = 3\n"
                   "planner_sigma = 0.2\nplanner_temperature = 0.5\nplanner_smoothing = 0.8\n"
                   "planner_terminal_steps = 7\n");
  const PlannerOptions o = planner_options(load_settings(path).mujoco);
  EXPECT_EQ(o.samples, 4);
  EXPECT_EQ(o.horizon, 5);
  EXPECT_EQ(o.iterations, 3);
  EXPECT_EQ(o.sigma, 0.2);
  EXPECT_EQ(o.temperature, 0.5);
  EXPECT_EQ(o.smoothing, 0.8);
  EXPECT_EQ(o.terminal_steps, 7.0);
  for (const char* env : {"halfcheetah", "hopper", "reacher"}) {
    const PlannerOptions a = planner_defaults(env, planner_options(Settings{}.mujoco));
    const PlannerOptions b = planner_defaults(env);
    EXPECT_EQ(a.samples, b.samples) << env;
    EXPECT_EQ(a.horizon, b.horizon) << env;
    EXPECT_EQ(a.iterations, b.iterations) << env;
    EXPECT_EQ(a.sigma, b.sigma) << env;
    EXPECT_EQ(a.temperature, b.temperature) << env;
    EXPECT_EQ(a.smoothing, b.smoothing) << env;
    EXPECT_EQ(a.terminal_steps, b.terminal_steps) << env;
  }
}

TEST(MujocoExpert, DefaultsFillOnlyWhatIsUnsetAndBadSmoothingIsOneLine) {
  PlannerOptions given;
  given.samples = 5;
  given.smoothing = 0.0;  // 0 is a value here (white noise), not "default"
  const PlannerOptions o = planner_defaults("halfcheetah", given);
  EXPECT_EQ(o.samples, 5);
  EXPECT_EQ(o.smoothing, 0.0);
  EXPECT_GT(o.horizon, 0);
  EXPECT_GT(o.iterations, 0);
  EXPECT_GT(o.sigma, 0.0);
  EXPECT_GT(o.temperature, 0.0);
  EXPECT_GE(o.terminal_steps, 0.0);
  given.smoothing = 1.0;
  try {
    planner_defaults("hopper", given);
    FAIL() << "smoothing 1 must throw";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("smoothing"), std::string::npos) << e.what();
    EXPECT_EQ(std::string(e.what()).find('\n'), std::string::npos) << e.what();
  }
}

TEST(MujocoExpert, IterationsCostSamplesTimesHorizonEachAndSmoothingStaysSeeded) {
  CD_NEEDS_MUJOCO();
  PlannerOptions p;
  p.samples = 6;
  p.horizon = 3;
  p.iterations = 2;
  p.smoothing = 0.7;
  p.terminal_steps = 5;
  p.seed = 11;
  PlannerExpert a("hopper", p), b("hopper", p);
  Env env("hopper");
  env.reset(4);
  const std::vector<double> x = a.act(env.state()), y = b.act(env.state());
  EXPECT_EQ(x, y);
  EXPECT_EQ(a.simulated_steps(), 6 * 3 * 2);
  p.seed = 12;
  PlannerExpert c("hopper", p);
  EXPECT_NE(c.act(env.state()), x) << "another seed draws other noise";
}

// The planner does what it is for: on reacher (no termination, cheap), a few steps of it bring
// the fingertip nearer the target than doing nothing does.
TEST(MujocoExpert, ReacherPlannerBeatsDoingNothing) {
  CD_NEEDS_MUJOCO();
  PlannerOptions p;
  p.samples = 16;
  p.horizon = 10;
  p.seed = 1;
  PlannerExpert expert("reacher", p);
  Env planned("reacher"), idle("reacher");
  planned.reset(5);
  idle.reset(5);
  double planned_return = 0, idle_return = 0;
  const std::vector<double> zero(2, 0.0);
  for (int t = 0; t < 15; ++t) {
    planned_return += planned.step(expert.act(planned.state())).reward;
    idle_return += idle.step(zero).reward;
  }
  EXPECT_GT(planned_return, idle_return);
}

}  // namespace
}  // namespace cd::mj
