#pragma once
// Deterministic random numbers for the core: splitmix64 over a 64-bit state kept in State.
// Never seeded from time or a random device.
#include <cstdint>

namespace arthrosim {

/// Advances *state and returns the next 64 random bits (splitmix64, Steele et al. 2014).
inline std::uint64_t NextRandom(std::uint64_t* state) {
  std::uint64_t z = (*state += 0x9e3779b97f4a7c15ull);
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
  return z ^ (z >> 31);
}

/// Uniform double in [0, 1) with 53 random bits.
inline double NextUniform(std::uint64_t* state) {
  return static_cast<double>(NextRandom(state) >> 11) * 0x1.0p-53;
}

}  // namespace arthrosim
