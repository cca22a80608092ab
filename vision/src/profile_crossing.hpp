// Stage 4's reading of one colour profile along a border (the paper's
// section 2.3; docs/vision.md "Stage 4: corners"): where the
// yellow-minus-blue score (or the blue margin) changes sign. Pure: no
// image, no allocation.
#pragma once

namespace tcpest {
namespace vision {
namespace detail {

// The zero crossing of `profile` (samples points at t = t0 + i dt; ok[i]
// false where the border had no image to sample, whose profile value is
// then never read) within [t_lo, t_hi] whose change has the sign of
// want_sign, the steepest over up to 2 sampled points either side of it.
// Writes its sub-sample parameter (linear between the two points around
// it) and that slope (the change over the span, times want_sign). False
// when there is none (or without a profile); a crossing needs both
// points around it sampled.
bool best_crossing(const double* profile, const bool* ok, int samples, double t0, double dt, double t_lo, double t_hi,
                   double want_sign, double& t_cross, double& best_slope) noexcept;

}  // namespace detail
}  // namespace vision
}  // namespace tcpest
