#include "tcpest/vision/guided_estimate.hpp"

#include <algorithm>
#include <array>

namespace tcpest {
namespace vision {

GuidedResult guided_rounds(FeatureExtractor& extractor, solver::PoseEstimator& estimator,
                           const solver::CameraModel& camera, const solver::InstrumentModel& model,
                           const ImageView& image, solver::SolveMode mode, const solver::Estimate& first,
                           const GuidedOptions& options) noexcept {
  GuidedResult out;
  out.estimate = first;
  const int rounds = std::min(std::max(options.rounds, 0), kMaxGuidedRounds);
  for (int round = 0; round < rounds && out.estimate.quality != solver::EstimateQuality::None; ++round) {
    const std::array<Corner, kNumCorners> previous = extractor.result().corners;
    solver::PoseVector fitted = out.estimate.r;
    const bool fit_ok = extractor.fit_pose_to_image(image, camera, model, fitted, out.fit).ok() &&
                        out.fit.rms_px <= options.max_fit_rms_px && out.fit.boundaries >= options.min_fit_boundaries &&
                        out.fit.silhouette_readings >= options.min_fit_silhouette_readings;
    if (!fit_ok) {
      break;
    }
    if (!extractor.refine_corners(image, camera, model, fitted).ok()) {
      extractor.restore_corners(previous);
      break;
    }
    solver::CornerObservation refined;
    corners_to_arrays(extractor.result(), refined.pixel, refined.visible);
    const solver::Estimate again = estimator.estimate(refined, mode, fitted);
    if (again.quality == solver::EstimateQuality::None) {
      extractor.restore_corners(previous);
      break;
    }
    out.estimate = again;
    out.rounds_kept = round + 1;
  }
  if (out.rounds_kept == 0) {
    extractor.restore_stage4_corners();
  }
  return out;
}

GuidedResult guided_estimate(FeatureExtractor& extractor, solver::PoseEstimator& estimator,
                             const solver::CameraModel& camera, const solver::InstrumentModel& model,
                             const ImageView& image, bool extraction_ok, solver::SolveMode mode,
                             const solver::PoseVector& start, const GuidedOptions& options) noexcept {
  solver::CornerObservation observed;  // none when extraction failed (the extractor keeps an older frame's)
  if (extraction_ok) {
    corners_to_arrays(extractor.result(), observed.pixel, observed.visible);
  }
  const solver::Estimate first = estimator.estimate(observed, mode, start);
  if (!extraction_ok) {
    GuidedResult out;
    out.estimate = first;
    return out;
  }
  return guided_rounds(extractor, estimator, camera, model, image, mode, first, options);
}

}  // namespace vision
}  // namespace tcpest
