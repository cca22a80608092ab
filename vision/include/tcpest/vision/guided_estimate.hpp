// One frame's estimate after stages 1-4, with the model-guided corners of
// docs/vision.md (ours, not the paper's): the pose solved from stage 4's
// corners; then, up to `rounds` times, the pose fitted to the image from it
// (FeatureExtractor::fit_pose_to_image), the corners re-measured around the
// fitted pose (refine_corners) and the pose solved again from them. Every
// solve is solver::PoseEstimator's (eq. 8, outlier rounds, validity test),
// so the control loop and the estimate/evaluate commands share all of it.
// Allocation-free; bounded by `rounds` (each: one fit of at most refine_fit_iterations
// iterations, one refinement, one estimate).
#pragma once

#include "tcpest/solver/pose_estimator.hpp"
#include "tcpest/vision/features.hpp"

namespace tcpest {
namespace vision {

struct GuidedOptions {
  int rounds = 1;                 // 0: stage 4's corners only (the paper's pipeline)
  // The image fit is trusted only with this much support: its robust RMS
  // residual, the boundaries whose arc it read, its silhouette readings.
  double max_fit_rms_px = 0.6;
  int min_fit_boundaries = 3;
  int min_fit_silhouette_readings = 12;
  // When stage 4's corners give no pose: a rough one from the labelled
  // regions (pose_from_regions), fitted to the image from a coarse start;
  // kept only if the fit passes the test above and the re-solve succeeds.
  bool from_regions = true;
};
constexpr int kMaxGuidedRounds = 4;

struct GuidedResult {
  solver::Estimate estimate{};
  int rounds_kept = 0;            // rounds whose corners and pose were kept
  ImageFitSummary fit{};          // of the last fit tried
  bool from_regions = false;      // the rounds started from pose_from_regions
};

// The rounds alone, from a first estimate solved from stage 4's corners
// (the loop times them as their own step). On return the extractor's
// corners are those of the kept estimate (stage 4's if no round was kept).
GuidedResult guided_rounds(FeatureExtractor& extractor, solver::PoseEstimator& estimator,
                           const solver::CameraModel& camera, const solver::InstrumentModel& model,
                           const ImageView& image, solver::SolveMode mode, const solver::Estimate& first,
                           const GuidedOptions& options) noexcept;

// The first solve and the rounds. `extraction_ok`: stages 1-4 succeeded
// (else no corners are used and the estimate is None).
GuidedResult guided_estimate(FeatureExtractor& extractor, solver::PoseEstimator& estimator,
                             const solver::CameraModel& camera, const solver::InstrumentModel& model,
                             const ImageView& image, bool extraction_ok, solver::SolveMode mode,
                             const solver::PoseVector& start, const GuidedOptions& options) noexcept;

}  // namespace vision
}  // namespace tcpest
