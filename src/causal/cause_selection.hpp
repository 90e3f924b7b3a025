#pragma once
// Cause selection of the cim family: the Granger test of every latent against the speed, the
// correction, the cap, and the Pearson check against the recorded ground truth.
#include <string>
#include <vector>

#include "app/settings.hpp"
#include "causal/granger.hpp"

namespace cd {

// Granger test of every latent against the speed.
struct LatentTest {
  int index = 0;
  GrangerTest test;
  double p_adjusted = 1;
  bool significant = false;  // p_adjusted <= alpha
  bool selected = false;     // an input of the speed predictor
};

struct CauseSelection {
  std::vector<LatentTest> tests;  // one per latent, by index
  // Significant latents by (p_adjusted, larger F, index), capped at cim.max_causes, as
  // indices in ascending order; the smallest-p latent alone when none is significant.
  std::vector<int> ranked;
  std::vector<int> selected;  // the predictor's inputs: `ranked`, or every latent (cim-mlp)
  int significant = 0;
  bool fallback = false;      // nothing was significant: `ranked` holds the best latent
  bool capped = false;        // more were significant than cim.max_causes
  long rows = 0;              // regression rows of the tests
  double threshold_p = 0;     // raw p-value at or below which a test is significant
};

// speed: one series per episode; latents[i]: latent i's series per episode (same lengths).
// use_all: cim-mlp (every latent is an input; the tests are still run and recorded).
CauseSelection select_causes(const std::vector<std::vector<double>>& speed,
                             const std::vector<std::vector<std::vector<double>>>& latents,
                             const CimSettings& cim, bool use_all);

// Pearson correlation; NaN when either series is constant or they are shorter than 2.
double pearson(const std::vector<double>& a, const std::vector<double>& b);

}  // namespace cd
