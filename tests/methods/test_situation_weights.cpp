// train.situation_weights (methods/policy_family): the balanced weights of a training split on
// hand-made episodes whose situations are known, and training with them (same seed, same
// bytes; other weights, other bytes).
#include <gtest/gtest.h>

#include <map>
#include <vector>

#include <torch/torch.h>

#include "../support/fake_episodes.hpp"
#include "../support/tiny_training.hpp"
#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "datasets/situation.hpp"
#include "methods/policy_family.hpp"

namespace cd {
namespace {

using test::TempDir;

Dataset fake_dataset(const std::string& dir, bool causes) {
  test::write_fake_folder(dir, 3, {.frames = 40, .situation_causes = causes});
  DatasetOptions o;
  o.history = 3;
  o.stride = 2;
  o.val_fraction = 0.34;
  return Dataset(load_episode_set(dir), o);
}

TEST(SituationWeights, EveryClassWeighsTheSameInAll) {
  TempDir dir("cd-situation-weights");
  Dataset data = fake_dataset(dir / "data", true);
  Settings s;
  EXPECT_TRUE(situation_weights(s, data).empty());  // "none", the default
  s.train.situation_weights = "balanced";
  s.train.situation_weight_max = 1000;
  std::vector<float> w = situation_weights(s, data);
  ASSERT_EQ(w.size(), data.train().size());
  // Per class: the sum of its samples' weights is N / C, whatever its size.
  std::map<int, double> sum;
  double total = 0;
  for (size_t i = 0; i < w.size(); ++i) {
    const SampleRef& r = data.train()[i];
    const PackedEpisode& ep = data.episodes().episodes[r.episode];
    sum[situation_class(situations_at(ep, r.t, 0.1))] += w[i];
    total += w[i];
  }
  EXPECT_NEAR(total / w.size(), 1.0, 1e-5);
  ASSERT_GE(sum.size(), 3u);
  for (const auto& [c, v] : sum)
    EXPECT_NEAR(v, static_cast<double>(w.size()) / sum.size(), 1e-3) << situation_names()[c];

  Dataset plain = fake_dataset(dir / "plain", false);
  try {
    situation_weights(s, plain);
    FAIL() << "no error";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("train.situation_weights: episode file"),
              std::string::npos)
        << e.what();
  }
}

std::string train_weights(const TempDir& dir, const std::string& name, const std::string& mode) {
  Settings s = test::tiny_family_settings();
  s.train.situation_weights = mode;
  return read_file_bytes(test::train_tiny_run(dir, "bc-oh", name, s) + "/best.pt");
}

TEST(SituationWeights, TrainingWithThemIsDeterministicAndDiffers) {
  torch::set_num_threads(1);
  TempDir dir("cd-situation-train");
  test::write_fake_folder(dir / "data", 3, {.frames = 40, .situation_causes = true});
  const std::string a = train_weights(dir, "a", "balanced");
  EXPECT_EQ(a, train_weights(dir, "b", "balanced"));
  EXPECT_NE(a, train_weights(dir, "c", "none"));
}

}  // namespace
}  // namespace cd
