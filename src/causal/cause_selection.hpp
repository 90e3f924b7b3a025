#pragma once
// Cause selection of the cim family: the Granger test of every latent against the speed, the
// rule that picks (cim.selection), the cap, and the Pearson check against the recorded ground
// truth. The rules:
//   bivariate    each latent's own F test; adjusted p <= alpha; ranked by p, then F.
//   conditional  each latent tested given the lags of all the others (one joint fit); adjusted
//                p <= alpha; ranked by p, then F. A latent that only echoes another's signal
//                adds nothing given it.
//   partial_r2   each latent's bivariate test, kept when its lags explain at least
//                cim.min_partial_r2 of the variance the speed's own lags leave; ranked by that
//                share. An effect size: with tens of thousands of autocorrelated rows nearly
//                every p underflows, while a share does not grow with the row count.
// When nothing passes, the best-ranked latent alone is picked (fallback).
#include <string>
#include <vector>

#include "app/settings.hpp"
#include "causal/granger.hpp"

namespace cd {

// Granger test of every latent against the speed.
struct LatentTest {
  int index = 0;
  GrangerTest test;  // bivariate, or conditional on every other latent (the rule's test)
  double p_adjusted = 1;
  bool significant = false;  // passes the rule (p_adjusted <= alpha, or the partial R^2 bound)
  bool selected = false;     // an input of the speed predictor
};

struct CauseSelection {
  std::string rule;               // cim.selection
  std::vector<LatentTest> tests;  // one per latent, by index
  // The latents that pass the rule, best first by the rule's ranking, capped at
  // cim.max_causes, as indices in ascending order; the best-ranked latent alone when none
  // passes.
  std::vector<int> ranked;
  std::vector<int> selected;  // the predictor's inputs: `ranked`, or every latent (cim-mlp)
  int significant = 0;
  bool fallback = false;      // nothing passed: `ranked` holds the best latent
  bool capped = false;        // more were significant than cim.max_causes
  long rows = 0;              // regression rows of the tests
  double threshold_p = 0;     // raw p-value at or below which a test is significant
};

// speed: one series per episode; latents[i]: latent i's series per episode (same lengths).
// use_all: cim-mlp (every latent is an input; the tests are still run and recorded).
// eligible: the latents the rule may pick (cim.candidates), empty = all; the others are
// tested and recorded but never significant, ranked or picked as the fallback.
CauseSelection select_causes(const std::vector<std::vector<double>>& speed,
                             const std::vector<std::vector<std::vector<double>>>& latents,
                             const CimSettings& cim, bool use_all,
                             const std::vector<bool>& eligible = {});

// Pearson correlation; NaN when either series is constant or they are shorter than 2.
double pearson(const std::vector<double>& a, const std::vector<double>& b);

}  // namespace cd
