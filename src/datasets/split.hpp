#pragma once
// How a data folder becomes training and validation samples: whole episodes held out, and a
// seeded subset when train.max_samples caps them. Every trainer splits this way.
#include <algorithm>
#include <cstdint>
#include <vector>

#include "core/rng.hpp"

namespace cd {

// A sample: step t of episode e (whatever the method makes of it).
struct SampleRef {
  int32_t episode = 0;
  int32_t t = 0;
  bool operator==(const SampleRef&) const = default;
};

// Which episodes validate: round(val_fraction * n) of them, at least one when n >= 2 and
// val_fraction > 0, never all; chosen by a seeded shuffle, returned sorted.
std::vector<int> choose_val_episodes(int episodes, double val_fraction, uint64_t seed);

// How a subset is drawn: a whole shuffle then its first n (bc), or a partial Fisher-Yates of n
// draws (dim, the cim family). Both are uniform; each method keeps the one its runs were made
// with, so its bytes do not move.
enum class SubsetDraw { Full, Partial };

// n of v chosen from rng, kept in their original order; v itself (no draw) when n >= size.
template <class T>
std::vector<T> subset_in_order(const std::vector<T>& v, size_t n, Rng& rng, SubsetDraw draw) {
  if (n >= v.size()) return v;
  std::vector<size_t> idx(v.size());
  for (size_t i = 0; i < idx.size(); ++i) idx[i] = i;
  if (draw == SubsetDraw::Full)
    shuffle(idx, rng);
  else
    partial_shuffle(idx, n, rng);
  idx.resize(n);
  std::sort(idx.begin(), idx.end());
  std::vector<T> out;
  out.reserve(n);
  for (size_t i : idx) out.push_back(v[i]);
  return out;
}

// train.max_samples over both splits: they shrink by the same fraction, validation keeps at
// least one sample when it has any. Nothing happens when max <= 0 or nothing is over it.
void cap_splits(std::vector<SampleRef>& train, std::vector<SampleRef>& val, long max, Rng& rng,
                SubsetDraw draw);

}  // namespace cd
