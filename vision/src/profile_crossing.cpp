// Stage 4's reading of one colour profile: its steepest zero crossing
// (profile_crossing.hpp).
#include "profile_crossing.hpp"

#include <cstddef>

namespace tcpest {
namespace vision {
namespace detail {

bool best_crossing(const double* profile, const bool* ok, int samples, double t0, double dt, double t_lo, double t_hi,
                   double want_sign, double& t_cross, double& best_slope) noexcept {
  bool found = false;
  best_slope = 0.0;
  if (profile == nullptr || ok == nullptr) {
    return false;
  }
  for (int i = 0; i + 1 < samples; ++i) {
    const double t = t0 + dt * static_cast<double>(i);
    if (t < t_lo || t + dt > t_hi) {
      continue;
    }
    const auto a = static_cast<std::size_t>(i);
    if (!ok[a] || !ok[a + 1U]) {
      continue;
    }
    const double fa = profile[a];
    const double fb = profile[a + 1U];
    if (!((fa < 0.0 && fb >= 0.0) || (fa >= 0.0 && fb < 0.0)) || (fb - fa) * want_sign <= 0.0) {
      continue;
    }
    // The slope's span: up to 2 samples either side, only over sampled
    // points (a and a + 1 are): an unsampled point holds no value of this
    // border (the image ends there).
    std::size_t lo = a >= 2U ? a - 2U : 0U;
    std::size_t hi = a + 3U < static_cast<std::size_t>(samples) ? a + 3U : static_cast<std::size_t>(samples - 1);
    while (!ok[lo]) {  // ends at a at the latest
      ++lo;
    }
    while (!ok[hi]) {  // ends at a + 1 at the latest
      --hi;
    }
    const double slope = (profile[hi] - profile[lo]) * want_sign;
    if (!found || slope > best_slope) {
      t_cross = t + dt * fa / (fa - fb);
      found = true;
      best_slope = slope;
    }
  }
  return found;
}

}  // namespace detail
}  // namespace vision
}  // namespace tcpest
