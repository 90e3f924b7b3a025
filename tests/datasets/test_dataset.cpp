// Training samples over hand-made episodes: history stacking and order, the first valid
// step, labels of both heads, the speed input, the validation split, subsets, and errors.
#include <gtest/gtest.h>

#include <set>
#include <string>
#include <vector>

#include "core/error.hpp"
#include "datasets/dataset.hpp"
#include "methods/method.hpp"
#include "../support/fake_episodes.hpp"

namespace cd {
namespace {

using test::FakeEpisodeSpec;
using test::TempDir;

// What fill() gives for one sample.
struct Filled {
  std::vector<float> image;
  float speed_in = -1;
  int64_t command = -1;
  std::vector<float> action;
  float speed_label = -1;
};

Filled fill(const Dataset& d, SampleRef s) {
  Filled f;
  f.image.assign(d.image_values(), -1.0f);
  f.action.assign(d.action_dim(), -1.0f);
  d.fill(s, {f.image.data(), &f.speed_in, &f.command, f.action.data(), &f.speed_label});
  return f;
}

// Decodes the step (channel 0) and episode (channel 1) from frame k of a stacked image.
int decode(const Dataset& d, const std::vector<float>& image, int k, int channel) {
  const EpisodeSet& s = d.episodes();
  const float* plane = image.data() + k * s.frame_values() + channel * s.frame_pixels();
  int v = 0;
  for (int i = 0; i < 16; ++i) v |= (plane[i] > 0.5f ? 1 : 0) << i;
  return v;
}

DatasetOptions options(int history, int stride, const std::string& head = "throttle_brake") {
  DatasetOptions o;
  o.history = history;
  o.stride = stride;
  o.action_head = head;
  o.val_fraction = 0;
  return o;
}

TEST(Dataset, StacksRealFramesOldestFirst) {
  TempDir dir("cd-learn");
  test::write_fake_folder(dir / "data", 2, {.frames = 30});
  Dataset d(load_episode_set(dir / "data"), options(4, 3));
  EXPECT_EQ(d.input_channels(), 4 * 8);
  EXPECT_EQ(d.first_step(), 9);
  // Every sample starts at t >= 9: no repeated frame at the start of an episode.
  ASSERT_EQ(d.train().size(), 2u * (30 - 9));
  EXPECT_EQ(d.train().front(), (SampleRef{0, 9}));
  EXPECT_EQ(d.train().back(), (SampleRef{1, 29}));
  for (const SampleRef& s : {SampleRef{0, 9}, SampleRef{1, 17}, SampleRef{1, 29}}) {
    Filled f = fill(d, s);
    for (int k = 0; k < 4; ++k) {
      EXPECT_EQ(decode(d, f.image, k, 0), s.t - (3 - k) * 3) << "frame " << k << " of t " << s.t;
      EXPECT_EQ(decode(d, f.image, k, 1), s.episode);
    }
    for (float v : f.image) ASSERT_TRUE(v == 0.0f || v == 1.0f);
  }
}

TEST(Dataset, PackedAndPlanarFilesGiveTheSameInput) {
  TempDir dir("cd-learn");
  test::write_fake_folder(dir / "planar", 1, {.frames = 12});
  test::write_fake_folder(dir / "packed", 1, {.frames = 12, .packed = true});
  Dataset a(load_episode_set(dir / "planar"), options(2, 1));
  Dataset b(load_episode_set(dir / "packed"), options(2, 1));
  ASSERT_EQ(a.train().size(), b.train().size());
  for (size_t i = 0; i < a.train().size(); ++i)
    ASSERT_EQ(fill(a, a.train()[i]).image, fill(b, b.train()[i]).image) << i;
}

TEST(Dataset, LabelsOfBothHeadsAndTheSpeedInput) {
  TempDir dir("cd-learn");
  test::write_fake_folder(dir / "data", 2, {.frames = 25});
  const EpisodeData ep1 = test::fake_episode(1, {.frames = 25});

  Dataset tb(load_episode_set(dir / "data"), options(2, 2));
  Filled f = fill(tb, {1, 13});
  ASSERT_EQ(f.action.size(), 2u);
  EXPECT_FLOAT_EQ(f.action[0], ep1.action[2 * 13]);
  EXPECT_FLOAT_EQ(f.action[1], ep1.action[2 * 13 + 1]);
  EXPECT_FLOAT_EQ(f.speed_label, ep1.speed[13]);
  EXPECT_EQ(f.speed_in, 0.0f) << "speed input must be zero unless model.speed_input";
  EXPECT_EQ(f.command, ep1.command[13]);
  EXPECT_EQ(tb.train().back(), (SampleRef{1, 24})) << "the last frame is a throttle_brake sample";

  DatasetOptions o = options(2, 2, "target_speed");
  o.speed_input = true;
  Dataset ts(load_episode_set(dir / "data"), o);
  Filled g = fill(ts, {1, 13});
  ASSERT_EQ(g.action.size(), 1u);
  EXPECT_FLOAT_EQ(g.action[0], ep1.speed[14]) << "target speed = the expert's next speed";
  EXPECT_FLOAT_EQ(g.speed_label, ep1.speed[13]);
  EXPECT_FLOAT_EQ(g.speed_in, ep1.speed[13]);
  // The last frame has no next speed: not a sample of this head.
  EXPECT_EQ(ts.train().back(), (SampleRef{1, 23}));
  EXPECT_EQ(ts.train().size(), tb.train().size() - 2);
}

TEST(Dataset, NoisyStepsGiveNoTargetSpeedSampleButKeepTheirActionLabel) {
  TempDir dir("cd-learn");
  test::write_fake_folder(dir / "data", 2, {.frames = 25});
  EpisodeSet set = load_episode_set(dir / "data");
  ASSERT_EQ(set.episodes[1].noise, std::vector<uint8_t>(25, 0)) << "written without a mask";
  // Episode 1 executed injected noise at steps 5, 6 and 7: speed[6..8] is the noise's motion.
  for (int t : {5, 6, 7}) set.episodes[1].noise[t] = 1;
  EXPECT_TRUE(expert_motion(set.episodes[1], 0, 5));
  EXPECT_FALSE(expert_motion(set.episodes[1], 4, 6));
  EXPECT_TRUE(expert_motion(set.episodes[1], 8, 25));

  auto steps_of = [](const std::vector<SampleRef>& list, int e) {
    std::vector<int> t;
    for (const SampleRef& s : list)
      if (s.episode == e) t.push_back(s.t);
    return t;
  };
  Dataset ts(set, options(2, 2, "target_speed"));
  std::vector<int> want;
  for (int t = 2; t < 24; ++t)
    if (t < 5 || t > 7) want.push_back(t);
  EXPECT_EQ(steps_of(ts.train(), 1), want);
  EXPECT_EQ(steps_of(ts.train(), 0).size(), 22u);  // the clean episode keeps every step
  // The action label is the expert's whatever was executed: every step stays a sample.
  Dataset tb(set, options(2, 2));
  EXPECT_EQ(steps_of(tb.train(), 1).size(), 23u);
}

TEST(Dataset, BcSoSeesOneFrame) {
  Settings s;
  s.model.history = 4;
  s.model.history_stride = 2;
  Settings so = effective_settings("bc-so", s), oh = effective_settings("bc-oh", s);
  EXPECT_EQ(so.model.history, 1);
  EXPECT_EQ(oh.model.history, 4);
  TempDir dir("cd-learn");
  test::write_fake_folder(dir / "data", 1, {.frames = 10});
  Dataset d(load_episode_set(dir / "data"), options(so.model.history, so.model.history_stride));
  EXPECT_EQ(d.train().front(), (SampleRef{0, 0}));
  EXPECT_EQ(decode(d, fill(d, {0, 7}).image, 0, 0), 7);
}

TEST(Dataset, ValidationSplitIsByEpisodeDisjointAndSeeded) {
  TempDir dir("cd-learn");
  test::write_fake_folder(dir / "data", 10, {.frames = 12, .height = 16, .width = 16});
  DatasetOptions o = options(2, 1);
  o.val_fraction = 0.3;
  o.seed = 7;
  Dataset a(load_episode_set(dir / "data"), o);
  Dataset b(load_episode_set(dir / "data"), o);
  ASSERT_EQ(a.val_episodes().size(), 3u);
  EXPECT_EQ(a.val_episodes(), b.val_episodes());
  EXPECT_EQ(a.train(), b.train());
  EXPECT_EQ(a.val(), b.val());
  std::set<int> train_eps, val_eps;
  for (const auto& s : a.train()) train_eps.insert(s.episode);
  for (const auto& s : a.val()) val_eps.insert(s.episode);
  EXPECT_EQ(val_eps.size(), 3u);
  EXPECT_EQ(train_eps.size(), 7u);
  for (int e : val_eps) EXPECT_EQ(train_eps.count(e), 0u) << "episode " << e << " in both";
  EXPECT_EQ(a.train().size() + a.val().size(), 10u * 11u);

  // Another seed picks other episodes (for these seeds), the same seed the same ones.
  std::vector<int> other = choose_val_episodes(10, 0.3, 8);
  EXPECT_EQ(choose_val_episodes(10, 0.3, 7), a.val_episodes());
  EXPECT_NE(other, a.val_episodes());
  // At least one validation episode as soon as there are two; never all of them.
  EXPECT_EQ(choose_val_episodes(2, 0.01, 0).size(), 1u);
  EXPECT_EQ(choose_val_episodes(1, 0.5, 0).size(), 0u);
  EXPECT_EQ(choose_val_episodes(3, 0.9, 0).size(), 2u);
  EXPECT_TRUE(choose_val_episodes(5, 0.0, 0).empty());
}

TEST(Dataset, MaxSamplesKeepsASeededSubset) {
  TempDir dir("cd-learn");
  test::write_fake_folder(dir / "data", 4, {.frames = 30, .height = 16, .width = 16});
  DatasetOptions o = options(2, 1);
  o.val_fraction = 0.25;
  o.max_samples = 20;
  Dataset a(load_episode_set(dir / "data"), o);
  Dataset b(load_episode_set(dir / "data"), o);
  EXPECT_EQ(a.train().size() + a.val().size(), 20u);
  EXPECT_GE(a.val().size(), 1u);
  EXPECT_EQ(a.train(), b.train());
  EXPECT_EQ(a.val(), b.val());
  for (const auto& s : a.val()) EXPECT_TRUE(a.is_val_episode(s.episode));
  for (const auto& s : a.train()) EXPECT_FALSE(a.is_val_episode(s.episode));
}

TEST(Dataset, ClearErrors) {
  TempDir dir("cd-learn");
  try {
    load_episode_set(dir / "missing");
    FAIL() << "no error for a missing folder";
  } catch (const DataError& e) {
    EXPECT_NE(std::string(e.what()).find("missing"), std::string::npos) << e.what();
  }
  test::fs::create_directories(dir / "empty");
  EXPECT_THROW(load_episode_set(dir / "empty"), DataError);

  test::write_fake_folder(dir / "bad", 2, {.frames = 10});
  test::write_text(dir / "bad/episode_000001.h5", "not an hdf5 file");
  try {
    load_episode_set(dir / "bad");
    FAIL() << "no error for a damaged file";
  } catch (const DataError& e) {
    EXPECT_NE(std::string(e.what()).find("episode_000001.h5"), std::string::npos) << e.what();
  }

  // Episodes too short for the history give no sample.
  test::write_fake_folder(dir / "short", 1, {.frames = 5});
  EXPECT_THROW(Dataset(load_episode_set(dir / "short"), options(4, 2)), DataError);
}

}  // namespace
}  // namespace cd
