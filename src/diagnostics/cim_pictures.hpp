#pragma once
// The figures of a cim run folder (PNG, no text; their meaning is in the README):
//
//   traversal.png  one row per latent of causes.json "ranked" (the Granger picks): the base
//                  frame, its reconstruction, then 7 decodings with that latent set to
//                  -3, -2, ..., 3 and the others at the base frame's mu (seed 000 fig. 4).
//                  Each image 64x64 scaled x2 (128 px), 2-px grey separators.
//   granger.png    -log10(p) of every latent's Granger test (clamped at 300), one bar per
//                  latent: red = selected cause, orange = significant but over the cap, grey =
//                  not significant; a blue line at -log10 of the raw-p threshold (alpha/m for
//                  bonferroni, alpha for none, the BH cut-off for bh).
#include <string>
#include <vector>

#include "nn/beta_vae.hpp"

namespace cd {

inline constexpr int kTraversalColumns = 9;   // base, reconstruction, 7 values
inline constexpr int kTraversalCell = 128;    // 64 px scaled x2
inline constexpr int kTraversalSeparator = 2;

// base_view: 64*64 values in [0, 1]. Writes nothing for an empty `latents`.
void write_traversal_png(const std::string& path, BetaVae& vae, const std::vector<float>& base_view,
                         const std::vector<int>& latents);

inline constexpr int kGrangerBarWidth = 6, kGrangerGap = 2, kGrangerHeight = 240,
                     kGrangerMargin = 10;
void write_granger_png(const std::string& path, const std::vector<double>& p_values,
                       const std::vector<bool>& selected, const std::vector<bool>& significant,
                       double threshold_p);

}  // namespace cd
