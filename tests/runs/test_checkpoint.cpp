// The checkpoint record of bc runs (runs/checkpoint) and its commit protocol, without training.
#include <gtest/gtest.h>

#include <string>

#include "../support/test_support.hpp"
#include "app/settings.hpp"
#include "core/error.hpp"
#include "runs/checkpoint.hpp"

namespace cd {
namespace {

using test::TempDir;

Checkpoint sample_checkpoint() {
  Settings s;
  Checkpoint c;
  c.method = "bc-oh";
  c.settings = settings_to_json(s);
  c.model = s.model;
  c.input = {8, 64, 64, 4, 2, 2, 0.1, 0.5, {"a", "b"}, "driving", ""};
  c.data_dir = "/data";
  c.train_samples = 100;
  c.val_samples = 10;
  c.train_episodes = 9;
  c.val_episodes = 1;
  c.device = "cpu";
  c.epochs_done = 2;
  c.best_epoch = 1;
  c.best_loss = 0.25;
  c.lr = 1e-4;
  c.bad_epochs = 1;
  c.metrics = {{1, 0.5, 0.25, 2e-4, 3.0, 1000.0}, {2, 0.4, std::nullopt, 1e-4, 3.5, 900.0}};
  return c;
}

TEST(Checkpoint, JsonRoundTrip) {
  Checkpoint c = sample_checkpoint();
  Checkpoint d = checkpoint_from_json(checkpoint_to_json(c), "test");
  EXPECT_EQ(checkpoint_to_json(d), checkpoint_to_json(c));
  EXPECT_EQ(d.model.history, c.model.history);
  EXPECT_EQ(d.model.backbone, c.model.backbone);
  EXPECT_FALSE(d.metrics[1].val_loss.has_value());
  EXPECT_EQ(test::split_lines(metrics_jsonl(d)).size(), 2u);

  nlohmann::json broken = checkpoint_to_json(c);
  broken.erase("lr");
  try {
    checkpoint_from_json(broken, "x/checkpoint.json");
    FAIL() << "a missing key is accepted";
  } catch (const DataError& e) {
    EXPECT_NE(std::string(e.what()).find("'lr'"), std::string::npos) << e.what();
  }
  broken = checkpoint_to_json(c);
  broken["metrics"].erase(1);
  EXPECT_THROW(checkpoint_from_json(broken, "x"), DataError) << "metrics must match epochs_done";
}

// Steering and MuJoCo-Image actions are signed: their checkpoints record the squash of the
// action output, and one without it (an earlier build's sigmoid, never negative) is refused.
TEST(Checkpoint, SignedActionsRecordTheirSquashAndOlderRecordsAreRefused) {
  Checkpoint c = sample_checkpoint();
  EXPECT_FALSE(checkpoint_to_json(c)["input"].contains("action_output"))
      << "a (throttle, brake) record keeps its bytes";
  c.input.action_dim = 3;
  c.input.action_output = "sigmoid_tanh";
  nlohmann::json j = checkpoint_to_json(c);
  EXPECT_EQ(j["input"]["action_output"], "sigmoid_tanh");
  EXPECT_EQ(checkpoint_from_json(j, "x").input.action_output, "sigmoid_tanh");
  for (const char* domain : {"driving", "mujoco"}) {
    nlohmann::json old = j;
    old["input"].erase("action_output");
    if (std::string(domain) == "mujoco") {
      old["input"]["domain"] = "mujoco";
      old["input"]["env"] = "hopper";
    }
    try {
      checkpoint_from_json(old, "run/checkpoint.json");
      FAIL() << domain << ": a signed-action record without its squash is accepted";
    } catch (const DataError& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find("run/checkpoint.json"), std::string::npos) << what;
      EXPECT_NE(what.find("retrain"), std::string::npos) << what;
      EXPECT_NE(what.find(std::string(domain) == "mujoco" ? "negative action" : "negative steer"),
                std::string::npos)
          << what;
    }
  }
}

// A run recorded before model.pedals existed learned two pedals: it reads back as "two", not as
// the later default "auto" (which would decode its two outputs as one signed value).
TEST(Checkpoint, ARecordWithoutPedalsLearnedTwo) {
  Checkpoint c = sample_checkpoint();
  nlohmann::json j = checkpoint_to_json(c);
  EXPECT_EQ(checkpoint_from_json(j, "x").model.pedals, "auto");  // as recorded
  j["settings"]["model"].erase("pedals");
  EXPECT_EQ(checkpoint_from_json(j, "x").model.pedals, "two");
}

TEST(Checkpoint, ReadingFolders) {
  TempDir dir("cd-learn");
  EXPECT_FALSE(read_checkpoint(dir.path()).has_value());
  EXPECT_THROW(require_checkpoint(dir.path()), DataError);
  EXPECT_THROW(require_checkpoint(dir / "missing"), DataError);
  test::write_text(dir / "checkpoint.json", "{ not json");
  EXPECT_THROW(read_checkpoint(dir.path()), DataError);
  test::write_text(dir / "checkpoint.json", checkpoint_to_json(sample_checkpoint()).dump());
  EXPECT_EQ(require_checkpoint(dir.path()).epochs_done, 2);
}

TEST(Checkpoint, PendingFilesOfTheCommittedEpochRollForward) {
  TempDir dir("cd-learn");
  test::write_text(dir / "model.pt", "epoch 1");
  test::write_text(dir / pending_name("model.pt", 2), "epoch 2");
  test::write_text(dir / pending_name("optimizer.pt", 2), "opt 2");
  test::write_text(dir / pending_name("model.pt", 3), "epoch 3, never committed");
  test::write_text(dir / "best.pt.123.tmp", "half written");
  test::write_text(dir / "notes.tmp", "the user's");
  test::write_text(dir / "mine.pending", "the user's");
  EXPECT_EQ(settle_pending_files(dir.path(), 2), 2);
  EXPECT_EQ(test::read_text(dir / "model.pt"), "epoch 2");
  EXPECT_EQ(test::read_text(dir / "optimizer.pt"), "opt 2");
  EXPECT_EQ(test::list_dir(dir.path()),
            (std::vector<std::string>{"mine.pending", "model.pt", "notes.tmp", "optimizer.pt"}));
  // Settling again changes nothing.
  EXPECT_EQ(settle_pending_files(dir.path(), 2), 0);
  EXPECT_EQ(test::read_text(dir / "model.pt"), "epoch 2");
}

}  // namespace
}  // namespace cd
