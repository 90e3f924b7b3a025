// The imitation diagnosis (diagnostics/diagnose): the statistics of hand-made predictions
// against hand computation, per situation.
#include "diagnostics/diagnose.hpp"

#include <gtest/gtest.h>

#include "../support/situation_masks.hpp"

#include <cmath>

#include <nlohmann/json.hpp>


namespace cd {
namespace {

using test::situation_bits;

std::vector<DiagnosedFrame> frames_of(const std::vector<float>& labels,
                                      const std::vector<float>& predictions) {
  std::vector<DiagnosedFrame> f;
  for (size_t i = 0; i < labels.size(); ++i)
    f.push_back({0, static_cast<int>(i), {labels[i]}, {predictions[i]}});
  return f;
}

TEST(Diagnose, PerfectPredictionHasR2OneAndConstantHasR2AtMostZero) {
  const std::vector<float> y = {0, 1, 2, 3};
  const std::vector<uint32_t> all(4, situation_bits({}));
  const ComponentStats perfect =
      summarize_diagnosis({"throttle"}, frames_of(y, y), all, kDrivingDomain)
          .situations[kAllFrames].components[0];
  EXPECT_EQ(perfect.count, 4);
  EXPECT_DOUBLE_EQ(perfect.r2, 1.0);
  EXPECT_DOUBLE_EQ(perfect.mae, 0.0);
  EXPECT_DOUBLE_EQ(perfect.label_mean, 1.5);
  EXPECT_NEAR(perfect.label_sd, std::sqrt(1.25), 1e-12);  // population sd
  EXPECT_NEAR(perfect.pred_sd, std::sqrt(1.25), 1e-12);

  // The mean as a constant: R^2 = 0. Another constant (1.0): SSE = 1 + 0 + 1 + 4 = 6,
  // SST = 5, R^2 = -0.2, MAE = (1 + 0 + 1 + 2) / 4 = 1.
  const ComponentStats at_mean =
      summarize_diagnosis({"throttle"}, frames_of(y, {1.5f, 1.5f, 1.5f, 1.5f}), all,
                          kDrivingDomain)
          .situations[kAllFrames].components[0];
  EXPECT_NEAR(at_mean.r2, 0.0, 1e-12);
  EXPECT_DOUBLE_EQ(at_mean.pred_sd, 0.0);
  const ComponentStats constant =
      summarize_diagnosis({"throttle"}, frames_of(y, {1, 1, 1, 1}), all, kDrivingDomain)
          .situations[kAllFrames].components[0];
  EXPECT_NEAR(constant.r2, -0.2, 1e-12);
  EXPECT_DOUBLE_EQ(constant.mae, 1.0);
  EXPECT_DOUBLE_EQ(constant.pred_mean, 1.0);
  // Constant labels: R^2 of a wrong prediction is undefined (null in JSON).
  DiagnosisReport flat =
      summarize_diagnosis({"brake"}, frames_of({0.3f, 0.3f}, {0.1f, 0.2f}),
                          {situation_bits({}), situation_bits({})}, kDrivingDomain);
  EXPECT_FALSE(flat.situations[kAllFrames].components[0].r2_defined);
  EXPECT_TRUE(diagnosis_json(flat)["situations"]["all"]["brake"]["r2"].is_null());
  EXPECT_NE(diagnosis_table(summarize_diagnosis({"throttle"}, frames_of(y, {1, 1, 1, 1}), all,
                                                kDrivingDomain))
                .find("flat"),
            std::string::npos);
}

TEST(Diagnose, EverySituationCountsItsOwnFramesPerComponent) {
  // Three frames: standing_free + starting, cruising, none. Two components.
  std::vector<DiagnosedFrame> f = {{0, 0, {1.0f, 0.0f}, {0.5f, 0.0f}},
                                   {0, 1, {0.1f, 0.0f}, {0.1f, 0.2f}},
                                   {0, 2, {0.0f, 0.3f}, {0.0f, 0.3f}}};
  const std::vector<uint32_t> m = {situation_bits({kStandingFree, kStarting}),
                                   situation_bits({kCruising}), situation_bits({})};
  DiagnosisReport r = summarize_diagnosis({"throttle", "brake"}, f, m, kDrivingDomain);
  ASSERT_EQ(r.situations.size(), static_cast<size_t>(kSituationCount));
  const std::vector<long> counts = {3, 1, 1, 1, 0, 0, 0, 0};
  for (int s = 0; s < kSituationCount; ++s) {
    EXPECT_EQ(r.situations[s].name, situation_names()[s]);
    EXPECT_EQ(r.situations[s].count, counts[s]) << situation_names()[s];
  }
  EXPECT_DOUBLE_EQ(r.situations[kStarting].components[0].mae, 0.5);
  EXPECT_NEAR(r.situations[kCruising].components[1].mae, 0.2, 1e-7);
  EXPECT_NEAR(r.situations[kAllFrames].components[0].mae, 0.5 / 3, 1e-7);
  EXPECT_NEAR(r.situations[kAllFrames].components[0].label_mean, 1.1 / 3, 1e-7);

  nlohmann::json j = diagnosis_json(r);
  for (const char* key : {"checkpoint", "frames", "situations"}) EXPECT_TRUE(j.contains(key));
  EXPECT_EQ(j["frames"], 3);
  EXPECT_EQ(j["situations"]["starting"]["count"], 1);
  for (const char* key : {"label_mean", "label_sd", "pred_mean", "pred_sd", "mae", "r2"})
    EXPECT_TRUE(j["situations"]["cruising"]["brake"].contains(key)) << key;
  // A situation without frames has null statistics.
  EXPECT_TRUE(j["situations"]["following"]["throttle"]["mae"].is_null());

  // MuJoCo-Image: the one situation "all".
  DiagnosisReport mj = summarize_diagnosis({"a0", "a1"}, f, {1, 1, 1}, "mujoco");
  ASSERT_EQ(mj.situations.size(), 1u);
  EXPECT_EQ(mj.situations[0].name, "all");
  EXPECT_EQ(mj.situations[0].count, 3);
}

}  // namespace
}  // namespace cd
