// MuJoCo-Image folders as training data (datasets/episode_set): RGB bytes kept as recorded
// behind planes01 (byte / 255) and planes255, the env's action size, command and speed zero;
// a Dataset over them; and the copycat measure of mujoco/eval (lag-1 R^2) on hand-made series.
#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "../support/test_support.hpp"
#include "data/mujoco_episode.hpp"
#include "datasets/dataset.hpp"
#include "datasets/episode_set.hpp"
#include "mujoco/collect.hpp"
#include "mujoco/eval.hpp"

namespace cd {
namespace {

std::string tiny_folder(const test::TempDir& dir) {
  mj::CollectOptions o;
  o.env = "reacher";
  o.out = dir / "data";
  o.episodes = 2;
  o.seed = 5;
  o.max_steps = 6;
  o.width = o.height = 16;
  o.planner.samples = 4;
  o.planner.horizon = 2;
  o.quiet = true;
  mj::collect(o);
  return o.out;
}

TEST(MujocoEpisodeSet, LoadsRgbBytesAsRecorded) {
  CD_NEEDS_MUJOCO();
  test::TempDir dir("cdtest-mjset");
  const std::string data = tiny_folder(dir);
  EXPECT_EQ(data_domain(data), "mujoco");
  const EpisodeSet set = load_episode_set(data);
  EXPECT_EQ(set.domain, "mujoco");
  EXPECT_EQ(set.env, "reacher");
  EXPECT_EQ(set.layout, FrameLayout::Bytes);
  EXPECT_EQ(set.channels, 3);
  EXPECT_EQ(set.height, 16);
  EXPECT_EQ(set.width, 16);
  EXPECT_EQ(set.action_dim, 2);
  ASSERT_EQ(set.episodes.size(), 2u);
  const MujocoEpisode raw = read_mujoco_episode(data + "/episode_000001.h5");
  const PackedEpisode& ep = set.episodes[1];
  ASSERT_EQ(ep.frames, static_cast<int>(raw.frames()));
  EXPECT_EQ(ep.action, raw.action);
  for (int t = 0; t < ep.frames; ++t) {
    EXPECT_EQ(ep.command[t], 0);
    EXPECT_EQ(ep.speed[t], 0.0f);
  }
  const size_t fv = set.frame_values();
  std::vector<float> unit(fv);
  std::vector<uint8_t> bytes(fv);
  bool varied = false;
  for (int t = 0; t < ep.frames; ++t) {
    set.planes01(1, t, unit.data());
    set.planes255(1, t, bytes.data());
    const uint8_t* want = raw.obs.data() + t * fv;
    for (size_t i = 0; i < fv; ++i) {
      ASSERT_EQ(bytes[i], want[i]) << "t " << t << " value " << i;
      ASSERT_EQ(unit[i], static_cast<float>(want[i]) / 255.0f) << "t " << t << " value " << i;
      varied |= want[i] != 0 && want[i] != 255;
    }
  }
  EXPECT_TRUE(varied) << "RGB frames should hold values other than 0 and 255";
}

TEST(MujocoEpisodeSet, DatasetSamplesCarryTheEnvsActions) {
  CD_NEEDS_MUJOCO();
  test::TempDir dir("cdtest-mjset");
  DatasetOptions opt;
  opt.history = 2;
  opt.stride = 1;
  opt.action_lags = 1;
  opt.val_fraction = 0.5;
  Dataset d(load_episode_set(tiny_folder(dir)), opt);
  EXPECT_EQ(d.action_dim(), 2);
  EXPECT_EQ(d.input_channels(), 6);
  const SampleRef s = d.train().front();
  std::vector<float> image(d.image_values()), action(2), previous(2);
  float speed = 1, label = 1;
  int64_t command = 9;
  d.fill(s, {image.data(), &speed, &command, action.data(), &label, previous.data()});
  const PackedEpisode& ep = d.episodes().episodes[s.episode];
  EXPECT_EQ(action[0], ep.action[2 * s.t]);
  EXPECT_EQ(previous[1], ep.action[2 * (s.t - 1) + 1]);
  EXPECT_EQ(command, 0);
  EXPECT_EQ(speed, 0.0f);
}

TEST(MujocoCopycat, LagOneR2OfHandMadeSeries) {
  // a_t = 0.5 a_{t-1} + 0.1 exactly: R^2 = 1.
  std::vector<float> exact = {1.0f, -1.0f};
  for (int t = 1; t < 20; ++t)
    for (int j = 0; j < 2; ++j) exact.push_back(0.5f * exact[2 * (t - 1) + j] + 0.1f);
  EXPECT_NEAR(mj::lag1_r2({exact}, 2), 1.0, 1e-6);
  // Alternating +1, -1 per component: perfectly predicted by a_t = -a_{t-1}.
  std::vector<float> flip;
  for (int t = 0; t < 10; ++t) flip.insert(flip.end(), {t % 2 ? 1.0f : -1.0f, t % 2 ? -1.0f : 1.0f});
  EXPECT_NEAR(mj::lag1_r2({flip}, 2), 1.0, 1e-9);
  // A sequence independent of its past (period 3 pattern in one component): R^2 < 1.
  std::vector<float> mixed;
  const float pattern[] = {0.0f, 1.0f, 1.0f, 0.0f, 0.0f, 1.0f, 0.0f, 1.0f};
  for (float v : pattern) mixed.push_back(v);
  const double r2 = mj::lag1_r2({mixed}, 1);
  EXPECT_LT(r2, 0.5);
  EXPECT_GE(r2, 0.0);
  // Constant actions or too few pairs: undefined.
  EXPECT_TRUE(std::isnan(mj::lag1_r2({{0.3f, 0.3f, 0.3f, 0.3f, 0.3f}}, 1)));
  EXPECT_TRUE(std::isnan(mj::lag1_r2({{0.1f, 0.2f}}, 1)));
  // Pairs never cross episodes: two exact series with different maps are not one line.
  EXPECT_NEAR(mj::lag1_r2({exact, exact}, 2), 1.0, 1e-6);
}

}  // namespace
}  // namespace cd
