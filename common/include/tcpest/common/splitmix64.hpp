// splitmix64: the 64-bit mix of a counter stepped by the golden ratio. The
// same numbers on every platform and compiler (no std:: distribution), so
// that rendered datasets, simulated noise and seeded test inputs are
// reproducible anywhere.
#pragma once

#include <cstdint>

namespace tcpest {

constexpr std::uint64_t kSplitMix64Step = 0x9E3779B97F4A7C15ULL;

// The output of a generator whose state is `x`: the mix of x + step.
constexpr std::uint64_t splitmix64(std::uint64_t x) noexcept {
  std::uint64_t z = x + kSplitMix64Step;
  z = (z ^ (z >> 30U)) * 0xBF58476D1CE4E5B9ULL;
  z = (z ^ (z >> 27U)) * 0x94D049BB133111EBULL;
  return z ^ (z >> 31U);
}

}  // namespace tcpest
