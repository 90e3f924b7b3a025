#include "causal/cause_selection.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>

#include "core/error.hpp"

namespace cd {

CauseSelection select_causes(const std::vector<std::vector<double>>& speed,
                             const std::vector<std::vector<std::vector<double>>>& latents,
                             const CimSettings& cim, bool use_all,
                             const std::vector<bool>& eligible) {
  CauseSelection sel;
  sel.rule = cim.selection;
  const int m = static_cast<int>(latents.size());
  if (m == 0) throw ConfigError("cause selection: no latent variables");
  if (!eligible.empty() && static_cast<int>(eligible.size()) != m)
    throw Error("cause selection: " + std::to_string(eligible.size()) + " eligibility flags for " +
                std::to_string(m) + " latents");
  auto may_pick = [&](int i) { return eligible.empty() || eligible[static_cast<size_t>(i)]; };
  if (!eligible.empty() && std::none_of(eligible.begin(), eligible.end(), [](bool b) { return b; }))
    throw DataError("cause selection: no latent may be picked (cim.candidates = \"active\" and no "
                    "latent of the VAE is active): train the VAE longer or use cim.candidates = \"all\"");
  const bool by_share = cim.selection == "partial_r2";
  if (!by_share && cim.selection != "bivariate" && cim.selection != "conditional")
    throw ConfigError("unknown cim.selection '" + cim.selection +
                      "' (available: bivariate, conditional, partial_r2)");
  std::vector<GrangerTest> tests;
  if (cim.selection == "conditional") {
    tests = conditional_f_tests(speed, latents, cim.lags);
  } else {
    for (int i = 0; i < m; ++i) tests.push_back(granger_f_test(speed, latents[i], cim.lags));
  }
  std::vector<double> p(m), share(m);
  sel.tests.resize(m);
  for (int i = 0; i < m; ++i) {
    sel.tests[i].index = i;
    sel.tests[i].test = tests[i];
    p[i] = tests[i].p_value;
    share[i] = -tests[i].partial_r2;  // ascending key: the largest share first
  }
  sel.rows = sel.tests[0].test.rows;
  const std::vector<double> adj = adjust_p_values(p, cim.correction);
  std::vector<int> significant;
  for (int i = 0; i < m; ++i) {
    sel.tests[i].p_adjusted = adj[i];
    sel.tests[i].significant =
        may_pick(i) && (by_share ? tests[i].partial_r2 >= cim.min_partial_r2 : adj[i] <= cim.alpha);
    if (sel.tests[i].significant) significant.push_back(i);
  }
  sel.significant = static_cast<int>(significant.size());

  // Threshold on the raw p-values (for the chart): alpha, alpha/m, or the BH cut-off
  // k*alpha/m of the largest rank k with p_(k) <= k*alpha/m (alpha/m when there is none).
  if (cim.correction == "none") {
    sel.threshold_p = cim.alpha;
  } else if (cim.correction == "bonferroni") {
    sel.threshold_p = cim.alpha / m;
  } else {
    std::vector<double> sorted = p;
    std::sort(sorted.begin(), sorted.end());
    sel.threshold_p = cim.alpha / m;
    for (int k = m; k >= 1; --k)
      if (sorted[k - 1] <= k * cim.alpha / m) {
        sel.threshold_p = k * cim.alpha / m;
        break;
      }
  }

  auto better = [&](int a, int b, const std::vector<double>& key) {
    if (key[a] != key[b]) return key[a] < key[b];
    if (sel.tests[a].test.f_stat != sel.tests[b].test.f_stat)
      return sel.tests[a].test.f_stat > sel.tests[b].test.f_stat;
    return a < b;
  };
  if (significant.empty()) {
    std::vector<int> all;
    for (int i = 0; i < m; ++i)
      if (may_pick(i)) all.push_back(i);
    sel.ranked = {*std::min_element(all.begin(), all.end(), [&](int a, int b) {
      return better(a, b, by_share ? share : p);
    })};
    sel.fallback = true;
  } else {
    std::sort(significant.begin(), significant.end(),
              [&](int a, int b) { return better(a, b, by_share ? share : adj); });
    if (cim.max_causes > 0 && static_cast<int>(significant.size()) > cim.max_causes) {
      significant.resize(cim.max_causes);
      sel.capped = true;
    }
    sel.ranked = significant;
    std::sort(sel.ranked.begin(), sel.ranked.end());
  }
  if (use_all) {
    sel.selected.resize(m);
    std::iota(sel.selected.begin(), sel.selected.end(), 0);
  } else {
    sel.selected = sel.ranked;
  }
  for (int i : sel.selected) sel.tests[i].selected = true;
  return sel;
}

double pearson(const std::vector<double>& a, const std::vector<double>& b) {
  const size_t n = std::min(a.size(), b.size());
  if (n < 2) return std::nan("");
  double ma = 0, mb = 0;
  for (size_t i = 0; i < n; ++i) {
    ma += a[i];
    mb += b[i];
  }
  ma /= n;
  mb /= n;
  double sab = 0, saa = 0, sbb = 0;
  for (size_t i = 0; i < n; ++i) {
    sab += (a[i] - ma) * (b[i] - mb);
    saa += (a[i] - ma) * (a[i] - ma);
    sbb += (b[i] - mb) * (b[i] - mb);
  }
  if (saa <= 0 || sbb <= 0 || !std::isfinite(sab)) return std::nan("");
  return sab / std::sqrt(saa * sbb);
}

}  // namespace cd
