#pragma once
// A situation mask (datasets/situation.hpp) from a list of situations; "all" is always set.
#include <cstdint>
#include <initializer_list>

#include "datasets/situation.hpp"

namespace cd::test {

inline uint32_t situation_bits(std::initializer_list<Situation> s) {
  uint32_t m = 1u << kAllFrames;
  for (Situation x : s) m |= 1u << x;
  return m;
}

}  // namespace cd::test
