// From measured corners to an estimate with its quality: the pose solve,
// the rejection of corners that disagree with the model at the estimate, and
// the test that tells a valid estimate from a degraded one. One definition,
// used by the control loop and by the estimate/evaluate commands, so that
// both judge the same frame the same way.
//
// Rejection: a detector can misplace a corner along the border (a boundary
// read off a flat tangency) or take the shaft's edge for the base stripe's;
// such a corner pulls the pose. When the RMS after a solve exceeds
// `outlier_trigger_rms_px`, corners farther from the model at the estimate
// than max(outlier_min_px, outlier_median_factor x median residual) are
// dropped and the pose solved again from the estimate, at most
// `outlier_rounds` times; a round is kept only if it lowers the RMS.
// Bounded: at most 1 + outlier_rounds solves. Allocation-free.
#pragma once

#include <array>
#include <cstdint>

#include "tcpest/solver/pose_solver.hpp"

namespace tcpest {
namespace solver {

enum class EstimateQuality : std::uint8_t {
  Valid,     // converged on >= min_corners_valid corners with RMS <= max_rms_valid_px
  Degraded,  // a pose was found (converged or at the iteration cap) but fails the validity test
  None,      // no pose: refused input, too few corners, non-finite or singular
};
const char* to_string(EstimateQuality quality) noexcept;

struct EstimateOptions {
  int min_corners_valid = 6;           // corners used by the final solve
  double max_rms_valid_px = 2.0;       // RMS reprojection error of the final solve
  int outlier_rounds = 2;              // 0 disables rejection; at most kMaxOutlierRounds
  double outlier_trigger_rms_px = 1.0; // rejection only above this RMS
  double outlier_min_px = 2.5;         // never reject a corner closer than this
  double outlier_median_factor = 3.0;  // ... or than this many median residuals
  int outlier_min_corners = 7;         // rejection needs at least this many corners in use
};
constexpr int kMaxOutlierRounds = 4;

// Checks ranges; false names nothing, the caller reports its own field.
bool options_valid(const EstimateOptions& options) noexcept;

struct Estimate {
  EstimateQuality quality = EstimateQuality::None;
  PoseVector r = PoseVector::Zero();   // the start when quality is None
  SolveSummary summary{};              // of the kept solve
  std::array<bool, kNumCorners> rejected{};  // dropped as disagreeing with the model
  int corners_rejected = 0;
  int solves = 0;
};

// The estimate against the robot's encoders (their joints at kLambda,
// kPhi, kTheta of `encoders`; the channel's pose is not theirs). An
// estimate whose insertion, or whose bend theta (cos phi, sin phi) (phi
// alone means nothing on a straight tube), lies farther from theirs than
// these tolerances is demoted one level: Valid -> Degraded -> None. The
// defaults are twice model.md's coarse prior (lambda +/- 3 mm, phi and
// theta +/- 0.2 rad), the accuracy the encoders are trusted to; an image
// fit that lands beyond it has most likely read something else (an
// occluder's edge, a decoy): docs/solver.md.
struct EncoderCheck {
  double lambda_tolerance_mm = 6.0;  // 0: not checked
  double bend_tolerance_rad = 0.5;   // 0: not checked
};

// Checks ranges (finite, >= 0).
bool encoder_check_valid(const EncoderCheck& check) noexcept;

// True when `estimate` lies beyond `check`'s tolerances of `encoders`;
// false when encoders or estimate are not finite, or the estimate has no
// pose. Changes nothing: a caller can ask before it decides.
bool disagrees_with_encoders(const Estimate& estimate, const PoseVector& encoders, const EncoderCheck& check) noexcept;

// Valid -> Degraded -> None (None stays None).
EstimateQuality demoted_one_level(EstimateQuality quality) noexcept;

// Applies `check` to `estimate`: demoted one level where
// disagrees_with_encoders. True when it was demoted.
bool check_against_encoders(Estimate& estimate, const PoseVector& encoders, const EncoderCheck& check) noexcept;

class PoseEstimator {
 public:
  // Keeps references: camera and model must outlive the estimator.
  PoseEstimator(const CameraModel& camera, const InstrumentModel& model,
                const EstimateOptions& options = EstimateOptions{}) noexcept;

  EstimateOptions& options() noexcept { return options_; }
  const EstimateOptions& options() const noexcept { return options_; }
  PoseSolver& solver() noexcept { return solver_; }

  Estimate estimate(const CornerObservation& observed, SolveMode mode, const PoseVector& start) noexcept;

 private:
  const CameraModel& camera_;
  const InstrumentModel& model_;
  EstimateOptions options_;
  PoseSolver solver_;
  CornerObservation working_{};
  CornerSet predicted_{};
};

}  // namespace solver
}  // namespace tcpest
