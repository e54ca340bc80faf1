// The one small random number generator of raylod: SplitMix64 (Steele, Lea
// and Flood 2014). Every consumer seeds its own state from (seed, pixel or
// ray index), so results do not depend on thread scheduling.
#pragma once

#include <cstdint>

namespace raylod {

// Advances state and returns the next 64 random bits.
inline uint64_t splitmix64(uint64_t& state) {
  uint64_t z = (state += 0x9e3779b97f4a7c15ull);
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
  return z ^ (z >> 31);
}

// Uniform double in [0, 1) from the top 53 bits.
inline double uniform01(uint64_t& state) { return double(splitmix64(state) >> 11) * 0x1.0p-53; }

}  // namespace raylod
