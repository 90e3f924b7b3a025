// The shared training loop (src/train/loop): which rows an epoch visits. train.epoch_samples 0
// is one seeded pass (the order every run had before the key existed); fewer samples are a
// prefix of that pass, more are whole further passes of their own seeds, cut at the count; the
// loop updates on exactly those rows and averages its loss over them.
#include <gtest/gtest.h>

#include <algorithm>
#include <map>
#include <vector>

#include <torch/torch.h>

#include "core/rng.hpp"
#include "train/loop.hpp"

namespace cd {
namespace {

LoopPlan plan_of(size_t train_size, size_t epoch_samples) {
  LoopPlan p;
  p.train_size = train_size;
  p.epoch_samples = epoch_samples;
  p.shuffle_seed = 11;
  p.batch_size = 4;
  return p;
}

TEST(TrainLoop, EpochOrderIsOnePassFewerOrSeveral) {
  const std::vector<uint32_t> pass = shuffled_order(10, derive_seed(11, 3));
  EXPECT_EQ(epoch_order(plan_of(10, 0), 3), pass);
  EXPECT_EQ(epoch_order(plan_of(10, 10), 3), pass);
  EXPECT_EQ(epoch_size(plan_of(10, 0)), 10u);

  const std::vector<uint32_t> few = epoch_order(plan_of(10, 4), 3);
  EXPECT_EQ(few, std::vector<uint32_t>(pass.begin(), pass.begin() + 4));
  EXPECT_NE(epoch_order(plan_of(10, 4), 4), few);  // another epoch, another subset

  const std::vector<uint32_t> many = epoch_order(plan_of(10, 25), 3);
  ASSERT_EQ(many.size(), 25u);
  EXPECT_EQ(std::vector<uint32_t>(many.begin(), many.begin() + 10), pass);
  std::map<uint32_t, int> count;
  for (uint32_t r : many) ++count[r];
  ASSERT_EQ(count.size(), 10u);
  int thrice = 0;
  for (auto [row, c] : count) {
    EXPECT_TRUE(c == 2 || c == 3) << row;
    thrice += c == 3;
  }
  EXPECT_EQ(thrice, 5);
  // The second pass is a permutation of its own, not the first one repeated.
  EXPECT_NE(std::vector<uint32_t>(many.begin() + 10, many.begin() + 20), pass);
  EXPECT_TRUE(epoch_order(plan_of(0, 8), 1).empty());
}

// Records the rows each update gets; the loss of a batch is its first row's index.
struct CountingObjective : Objective {
  std::vector<uint32_t> seen;
  BatchLoss loss(bool, const uint32_t* rows, int64_t) override {
    return {torch::tensor(static_cast<double>(rows[0])), {}};
  }
  void set_training(bool) override {}
  BatchLoss update(const uint32_t* rows, int64_t n, torch::optim::Optimizer&, double) override {
    seen.insert(seen.end(), rows, rows + n);
    return {torch::tensor(1.0 + static_cast<double>(n)), {}};
  }
};

TEST(TrainLoop, TrainsOnTheEpochsRowsAndAveragesOverThem) {
  torch::Tensor w = torch::zeros({1}, torch::requires_grad());
  torch::optim::Adam opt({w}, 1e-3);
  CountingObjective objective;
  LoopPlan plan = plan_of(10, 25);
  plan.first_epoch = 1;
  plan.last_epoch = 2;
  LoopState state;
  state.lr = 1e-3;
  std::vector<EpochResult> results;
  const LoopTotals totals =
      train_epochs(objective, opt, plan, state, [&](const EpochResult& r) { results.push_back(r); });
  EXPECT_EQ(totals.samples, 50);
  std::vector<uint32_t> want = epoch_order(plan, 1);
  const std::vector<uint32_t> second = epoch_order(plan, 2);
  want.insert(want.end(), second.begin(), second.end());
  EXPECT_EQ(objective.seen, want);
  ASSERT_EQ(results.size(), 2u);
  // Batches of 4 over 25 rows: six of loss 5 (n = 4) and one of loss 2 (n = 1), weighted by n.
  EXPECT_DOUBLE_EQ(results[0].train_loss, (6 * 4 * 5.0 + 1 * 2.0) / 25.0);
}

}  // namespace
}  // namespace cd
