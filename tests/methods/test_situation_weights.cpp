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
#include "runs/checkpoint.hpp"

namespace cd {
using nlohmann::json;
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
  s.train.situation_weights = "none";
  EXPECT_TRUE(situation_weights(s, data).empty());
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
    EXPECT_NE(std::string(e.what()).find("train.situation_weights = \"balanced\": episode file"),
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

// The built-in defaults are the validated recipe (configs/residual_paper.toml): "auto" resolves
// to signed pedals and balanced weights on driving data with its causes, to neither on
// MuJoCo's; collection holds the first second.
TEST(SituationWeights, TheDefaultsAreTheRecipeResolvedPerDomain) {
  const Settings d;
  EXPECT_DOUBLE_EQ(d.collect.hold_s, 1.0);
  const Settings drive = resolve_recipe(d, "driving", true);
  EXPECT_EQ(drive.model.pedals, "signed");
  EXPECT_EQ(drive.train.situation_weights, "balanced");
  // Driving data without the causes (not collect's): no weights, still signed pedals.
  const Settings no_causes = resolve_recipe(d, "driving", false);
  EXPECT_EQ(no_causes.model.pedals, "signed");
  EXPECT_EQ(no_causes.train.situation_weights, "none");
  const Settings mujoco = resolve_recipe(d, "mujoco", false);
  EXPECT_EQ(mujoco.model.pedals, "two");
  EXPECT_EQ(mujoco.train.situation_weights, "none");
  Settings speed = d;
  speed.model.action_head = "target_speed";
  EXPECT_EQ(resolve_recipe(speed, "driving", true).model.pedals, "two");
  Settings old = d;  // explicit values stay
  old.model.pedals = "two";
  old.train.situation_weights = "none";
  const Settings kept = resolve_recipe(old, "driving", true);
  EXPECT_EQ(kept.model.pedals, "two");
  EXPECT_EQ(kept.train.situation_weights, "none");
}

// Training with no config (the built-in defaults, only the thread count and device set) records the
// recipe's resolved settings and gives the same bytes as the recipe written out.
TEST(SituationWeights, TrainingWithNoConfigRecordsTheRecipe) {
  torch::set_num_threads(1);
  TempDir dir("cd-situation-defaults");
  test::write_fake_folder(dir / "data", 3, {.frames = 40, .situation_causes = true});
  Settings defaults;
  defaults.train.threads = 1;
  defaults.train.device = "cpu";  // same bytes are the CPU's
  defaults.train.epochs = 2;
  const std::string run = test::train_tiny_run(dir, "bc-oh", "defaults", defaults);
  const json record = json::parse(read_file_bytes(run + "/checkpoint.json"));
  EXPECT_EQ(record.at("settings").at("model").at("pedals"), "signed");
  EXPECT_EQ(record.at("settings").at("train").at("situation_weights"), "balanced");
  EXPECT_EQ(record.at("settings").at("collect").at("hold_s"), 1.0);
  EXPECT_EQ(record.at("input").at("action_output"), "tanh");
  Settings written = defaults;
  written.model.pedals = "signed";
  written.train.situation_weights = "balanced";
  EXPECT_EQ(read_file_bytes(run + "/best.pt"),
            read_file_bytes(test::train_tiny_run(dir, "bc-oh", "written", written) + "/best.pt"));
  Settings old = defaults;
  old.model.pedals = "two";
  old.train.situation_weights = "none";
  const json old_record = json::parse(
      read_file_bytes(test::train_tiny_run(dir, "bc-oh", "old", old) + "/checkpoint.json"));
  EXPECT_EQ(old_record.at("settings").at("model").at("pedals"), "two");
  EXPECT_FALSE(old_record.at("input").contains("action_output"));  // two sigmoids
  // Driving data that records no causes: the defaults weigh nothing, and the record says so.
  test::write_fake_folder(dir / "plain", 3, {.frames = 40, .situation_causes = false});
  const json plain = json::parse(read_file_bytes(
      test::train_tiny_run(dir, "bc-oh", "plain-run", defaults, "plain") + "/checkpoint.json"));
  EXPECT_EQ(plain.at("settings").at("train").at("situation_weights"), "none");
  EXPECT_EQ(plain.at("settings").at("model").at("pedals"), "signed");
}

}  // namespace
}  // namespace cd
