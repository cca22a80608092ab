// Deterministic random numbers for the renderer and the datasets: splitmix64
// (a counter-based generator: the same seed gives the same stream on every
// platform, and independent streams are derived by mixing in a key).
#pragma once

#include <cmath>
#include <cstdint>

#include "tcpest/common/dmath.hpp"
#include "tcpest/common/splitmix64.hpp"

namespace tcpest {
namespace render {

class Random {
 public:
  explicit Random(std::uint64_t seed, std::uint64_t stream = 0U) noexcept
      : state_(splitmix64(seed ^ splitmix64(stream + 0x632BE59BD9B4E019ULL))) {}
  std::uint64_t next() noexcept {
    const std::uint64_t z = splitmix64(state_);
    state_ += kSplitMix64Step;
    return z;
  }
  // Uniform in [0, 1).
  double uniform() noexcept { return static_cast<double>(next() >> 11U) * (1.0 / 9007199254740992.0); }
  double uniform(double lo, double hi) noexcept { return lo + (hi - lo) * uniform(); }
  // Standard normal (Box-Muller; one value per call keeps the stream simple).
  double normal() noexcept {
    const double u1 = 1.0 - uniform();  // (0, 1]
    const double u2 = uniform();
    return std::sqrt(-2.0 * dmath::log(u1)) * dmath::cos(6.283185307179586 * u2);
  }
  int below(int n) noexcept { return static_cast<int>(next() % static_cast<std::uint64_t>(n)); }

 private:
  std::uint64_t state_;
};

}  // namespace render
}  // namespace tcpest
