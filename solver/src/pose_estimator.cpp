#include "tcpest/solver/pose_estimator.hpp"

#include <algorithm>
#include <cmath>
#include <cstddef>

#include "tcpest/common/dmath.hpp"

namespace tcpest {
namespace solver {

namespace {

// A pose the caller may use: converged, or stopped at the iteration cap with
// a finite cost (still the best point found).
bool usable(const SolveSummary& s, const PoseVector& r) noexcept {
  const bool ended_well =
      is_converged(s.status) || (s.status == SolveStatus::MaxIterations && std::isfinite(s.final_cost));
  return ended_well && r.allFinite();
}

}  // namespace

const char* to_string(EstimateQuality quality) noexcept {
  switch (quality) {
    case EstimateQuality::Valid: return "valid";
    case EstimateQuality::Degraded: return "degraded";
    case EstimateQuality::None: return "none";
  }
  return "none";
}

bool options_valid(const EstimateOptions& o) noexcept {
  return o.min_corners_valid >= kMinCorners && o.min_corners_valid <= kNumCorners && o.max_rms_valid_px >= 0.0 &&
         std::isfinite(o.max_rms_valid_px) && o.outlier_rounds >= 0 && o.outlier_rounds <= kMaxOutlierRounds &&
         o.outlier_trigger_rms_px >= 0.0 && std::isfinite(o.outlier_trigger_rms_px) && o.outlier_min_px >= 0.0 &&
         std::isfinite(o.outlier_min_px) && o.outlier_median_factor >= 1.0 && std::isfinite(o.outlier_median_factor) &&
         o.outlier_min_corners > kMinCorners && o.outlier_min_corners <= kNumCorners;
}

bool encoder_check_valid(const EncoderCheck& check) noexcept {
  return std::isfinite(check.lambda_tolerance_mm) && check.lambda_tolerance_mm >= 0.0 &&
         std::isfinite(check.bend_tolerance_rad) && check.bend_tolerance_rad >= 0.0;
}

bool disagrees_with_encoders(const Estimate& estimate, const PoseVector& encoders, const EncoderCheck& check) noexcept {
  if (estimate.quality == EstimateQuality::None || !estimate.r.allFinite() || !encoders.allFinite()) {
    return false;
  }
  const PoseVector& r = estimate.r;
  const bool insertion_off = check.lambda_tolerance_mm > 0.0 &&
                             std::fabs(r[kLambda] - encoders[kLambda]) > check.lambda_tolerance_mm;
  const double bend_dx = r[kTheta] * dmath::cos(r[kPhi]) - encoders[kTheta] * dmath::cos(encoders[kPhi]);
  const double bend_dy = r[kTheta] * dmath::sin(r[kPhi]) - encoders[kTheta] * dmath::sin(encoders[kPhi]);
  const bool bend_off = check.bend_tolerance_rad > 0.0 && dmath::hypot(bend_dx, bend_dy) > check.bend_tolerance_rad;
  return insertion_off || bend_off;
}

EstimateQuality demoted_one_level(EstimateQuality quality) noexcept {
  return quality == EstimateQuality::Valid ? EstimateQuality::Degraded : EstimateQuality::None;
}

bool check_against_encoders(Estimate& estimate, const PoseVector& encoders, const EncoderCheck& check) noexcept {
  if (!disagrees_with_encoders(estimate, encoders, check)) {
    return false;
  }
  estimate.quality = demoted_one_level(estimate.quality);
  return true;
}

PoseEstimator::PoseEstimator(const CameraModel& camera, const InstrumentModel& model,
                             const EstimateOptions& options) noexcept
    : camera_(camera), model_(model), options_(options), solver_(camera, model) {}

Estimate PoseEstimator::estimate(const CornerObservation& observed, SolveMode mode, const PoseVector& start) noexcept {
  Estimate out;
  out.r = start;
  working_ = observed;
  PoseVector r = start;
  out.summary = solver_.solve(working_, mode, r);
  out.solves = 1;
  if (!usable(out.summary, r)) {
    out.r = start;
    return out;
  }
  const int rounds = std::min(std::max(options_.outlier_rounds, 0), kMaxOutlierRounds);
  for (int round = 0; round < rounds && out.summary.rms_px > options_.outlier_trigger_rms_px; ++round) {
    model_.corners(camera_, r, predicted_);
    std::array<double, kNumCorners> residual{};
    std::array<double, kNumCorners> sorted{};
    std::size_t n = 0U;
    for (std::size_t k = 0U; k < static_cast<std::size_t>(kNumCorners); ++k) {
      if (out.summary.used[k] && predicted_.present[k]) {
        residual[k] = (working_.pixel[k] - predicted_.pixel[k]).norm();
        sorted[n++] = residual[k];
      }
    }
    if (n < static_cast<std::size_t>(options_.outlier_min_corners)) {
      break;
    }
    const auto middle = sorted.begin() + static_cast<std::ptrdiff_t>(n / 2U);
    std::nth_element(sorted.begin(), middle, sorted.begin() + static_cast<std::ptrdiff_t>(n));
    const double limit = std::max(options_.outlier_min_px, options_.outlier_median_factor * *middle);
    CornerObservation trial = working_;
    std::array<bool, kNumCorners> dropped{};
    int removed = 0;
    for (std::size_t k = 0U; k < static_cast<std::size_t>(kNumCorners); ++k) {
      if (trial.visible[k] && (!predicted_.present[k] || residual[k] > limit)) {
        trial.visible[k] = false;
        dropped[k] = true;
        ++removed;
      }
    }
    if (removed == 0 || trial.count_visible() < options_.min_corners_valid) {
      break;
    }
    PoseVector retry = r;
    const SolveSummary again = solver_.solve(trial, mode, retry);
    ++out.solves;
    if (!usable(again, retry) || !(again.rms_px < out.summary.rms_px)) {
      break;
    }
    out.summary = again;
    r = retry;
    working_ = trial;
    for (std::size_t k = 0U; k < static_cast<std::size_t>(kNumCorners); ++k) {
      if (dropped[k]) {
        out.rejected[k] = true;
        ++out.corners_rejected;
      }
    }
  }
  out.r = r;
  const bool good = is_converged(out.summary.status) && out.summary.corners_used >= options_.min_corners_valid &&
                    out.summary.rms_px <= options_.max_rms_valid_px;
  out.quality = good ? EstimateQuality::Valid : EstimateQuality::Degraded;
  return out;
}

}  // namespace solver
}  // namespace tcpest
