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
#include "app/settings.hpp"
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

// A float loss with a part, of batch-dependent values (as a network's are).
struct FloatObjective : Objective {
  BatchLoss loss(bool, const uint32_t* rows, int64_t) override {
    return {torch::tensor(static_cast<float>(rows[0]) / 7.0f), {}};
  }
  void set_training(bool) override {}
  BatchLoss update(const uint32_t* rows, int64_t n, torch::optim::Optimizer&, double) override {
    const float v = 0.1f + static_cast<float>(rows[0] % 5) / 3.0f + static_cast<float>(n) / 11.0f;
    return {torch::tensor(v), {torch::tensor(v / 2.0f)}};
  }
};

TEST(TrainLoop, LossesReadOncePerEpochGiveTheMeanOfReadingEachBatch) {
  // On CUDA a read waits for the queued steps: LossReads::Epoch reads the epoch's sum once, so
  // the CPU fills the next batch while the GPU runs; its mean must be the per-batch one's.
  auto run = [](LoopPlan::LossReads reads) {
    torch::Tensor w = torch::zeros({1}, torch::requires_grad());
    torch::optim::Adam opt({w}, 1e-3);
    FloatObjective objective;
    LoopPlan plan = plan_of(10, 25);
    plan.last_epoch = 2;
    plan.loss_reads = reads;
    LoopState state;
    state.lr = 1e-3;
    std::vector<EpochResult> results;
    train_epochs(objective, opt, plan, state, [&](const EpochResult& r) { results.push_back(r); });
    return results;
  };
  const std::vector<EpochResult> each = run(LoopPlan::LossReads::Batch);
  const std::vector<EpochResult> once = run(LoopPlan::LossReads::Epoch);
  const std::vector<EpochResult> cpu = run(LoopPlan::LossReads::Auto);
  ASSERT_EQ(each.size(), 2u);
  ASSERT_EQ(once.size(), 2u);
  for (size_t e = 0; e < 2; ++e) {
    EXPECT_EQ(each[e].loss_reads, 7) << "25 rows in batches of 4: 7 reads";
    EXPECT_EQ(once[e].loss_reads, 1) << "one read at the epoch's end (no progress to feed)";
    EXPECT_EQ(cpu[e].loss_reads, 7) << "Auto reads each batch on the CPU";
    EXPECT_DOUBLE_EQ(once[e].train_loss, each[e].train_loss);
    ASSERT_EQ(once[e].train_parts.size(), 1u);
    EXPECT_DOUBLE_EQ(once[e].train_parts[0], each[e].train_parts[0]);
    EXPECT_DOUBLE_EQ(cpu[e].train_loss, each[e].train_loss);
  }
}

// Its loss (train and selection) follows a script, one value per epoch.
struct ScriptedObjective : Objective {
  std::vector<double> losses;
  int epoch = 0;
  BatchLoss loss(bool, const uint32_t*, int64_t) override { return {torch::tensor(0.0), {}}; }
  void set_training(bool) override {}
  BatchLoss update(const uint32_t*, int64_t, torch::optim::Optimizer&, double) override {
    return {torch::tensor(losses.at(static_cast<size_t>(epoch))), {}};
  }
};

// Trains with the early-stop rule; returns the epochs the callback saw.
std::vector<int> epochs_with_stop(std::vector<double> losses, int patience, double min_improvement,
                                  LoopTotals& totals) {
  torch::Tensor w = torch::zeros({1}, torch::requires_grad());
  torch::optim::Adam opt({w}, 1e-3);
  ScriptedObjective objective;
  objective.losses = std::move(losses);
  LoopPlan plan = plan_of(4, 0);
  plan.last_epoch = static_cast<int>(objective.losses.size());
  plan.stop_patience = patience;
  plan.stop_min_improvement = min_improvement;
  LoopState state;
  std::vector<int> seen;
  totals = train_epochs(objective, opt, plan, state, [&](const EpochResult& r) {
    seen.push_back(r.epoch);
    ++objective.epoch;
  });
  return seen;
}

TEST(TrainLoop, StopsOnceTheLossStopsFallingByTheMargin) {
  LoopTotals t;
  // 100 -> 90 (a clear gain), then 89.5 and 89.2: less than 1% under 90 twice -> stop after 4.
  EXPECT_EQ(epochs_with_stop({100, 90, 89.5, 89.2, 50, 40}, 2, 0.01, t),
            (std::vector<int>{1, 2, 3, 4}));
  EXPECT_TRUE(t.stopped_early);
  EXPECT_EQ(t.last_epoch, 4);
  // A clear gain (89 < 90 - 0.9) restarts the count: 3 stalls are needed after epoch 4.
  EXPECT_EQ(epochs_with_stop({100, 90, 89.5, 89.0, 88.9, 88.5, 88.4, 10}, 2, 0.01, t),
            (std::vector<int>{1, 2, 3, 4, 5, 6}));
  // Margin 0: any better loss counts; a worse one is a stall.
  EXPECT_EQ(epochs_with_stop({5, 4, 4.5, 3.9, 4.0, 4.1, 1}, 2, 0.0, t),
            (std::vector<int>{1, 2, 3, 4, 5, 6}));
  // Patience 0 trains every epoch; so does a rule that never fires before the last one.
  EXPECT_EQ(epochs_with_stop({5, 5, 5, 5}, 0, 0.01, t).size(), 4u);
  EXPECT_FALSE(t.stopped_early);
  EXPECT_EQ(t.last_epoch, 4);
  EXPECT_EQ(epochs_with_stop({5, 4, 3, 3}, 1, 0.0, t).size(), 4u);
  EXPECT_FALSE(t.stopped_early);  // the stall came at the last epoch anyway
}

// train.flush_denormals: 1e-20 * 1e-20 = 1e-40 is a denormal float. Flushed, every product is 0,
// on the main thread and on torch's second intra-op thread alike (the element-wise product of a
// large tensor is split between them, the matrix product runs in OpenBLAS's threads); kept, it
// is not, and 512 of them add up to a normal float.
TEST(TrainLoop, FlushDenormalsZeroesTinyProductsOnEveryThread) {
  const int threads_before = at::get_num_threads();
  TrainSettings train;
  train.device = "cpu";
  train.threads = 2;
  train.flush_denormals = true;
  const ComputeDevice dev = training_device(train);
  EXPECT_EQ(dev.name, "cpu");
  const torch::Tensor a = torch::full({512, 512}, 1e-20f);
  EXPECT_EQ(torch::count_nonzero(a * a).item<int64_t>(), 0);
  EXPECT_EQ(torch::count_nonzero(torch::mm(a, a)).item<int64_t>(), 0);

  train.flush_denormals = false;
  training_device(train);
  EXPECT_EQ(torch::count_nonzero(a * a).item<int64_t>(), 512 * 512);
  const torch::Tensor sums = torch::mm(a, a);
  EXPECT_EQ(torch::count_nonzero(sums).item<int64_t>(), 512 * 512);
  EXPECT_NEAR(sums[0][0].item<float>() / 5.12e-38f, 1.0, 1e-3);
  torch::set_num_threads(threads_before);
}

}  // namespace
}  // namespace cd
