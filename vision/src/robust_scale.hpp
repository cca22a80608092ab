// The robust scale of the fits (private header): the median and the MAD's
// factor to a standard deviation, for the image fits' Tukey cut
// (robust_step.hpp), stage 3's Bezier IRLS and the learned part widths.
#pragma once

#include <algorithm>

namespace tcpest {
namespace vision {
namespace detail {

// Median of v[0..n) (reorders v). n >= 1.
inline double median_of(double* v, int n) noexcept {
  std::sort(v, v + n);
  return (n % 2 == 1) ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

// The median absolute deviation times this is a normal distribution's
// standard deviation (the robust scale of every fit here).
constexpr double kMadToSigma = 1.4826;

}  // namespace detail
}  // namespace vision
}  // namespace tcpest
