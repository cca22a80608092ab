#include "tcpest/vision/guided_estimate.hpp"

#include <algorithm>
#include <array>

namespace tcpest {
namespace vision {

namespace {

GuidedResult rounds_from(FeatureExtractor& extractor, solver::PoseEstimator& estimator,
                         const solver::CameraModel& camera, const solver::InstrumentModel& model,
                         const ImageView& image, solver::SolveMode mode, const solver::Estimate& first,
                         const GuidedOptions& options, bool coarse_start) noexcept {
  GuidedResult out;
  out.estimate = first;
  const int rounds = std::min(std::max(options.rounds, 0), kMaxGuidedRounds);
  for (int round = 0; round < rounds && out.estimate.quality != solver::EstimateQuality::None; ++round) {
    const std::array<Corner, kNumCorners> previous = extractor.result().corners;
    solver::PoseVector fitted = out.estimate.r;
    const bool fit_ok = extractor.fit_pose_to_image(image, camera, model, fitted, out.fit, coarse_start && round == 0).ok() &&
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

}  // namespace

GuidedResult guided_rounds(FeatureExtractor& extractor, solver::PoseEstimator& estimator,
                           const solver::CameraModel& camera, const solver::InstrumentModel& model,
                           const ImageView& image, solver::SolveMode mode, const solver::Estimate& first,
                           const GuidedOptions& options) noexcept {
  return rounds_from(extractor, estimator, camera, model, image, mode, first, options, false);
}

GuidedResult guided_estimate(FeatureExtractor& extractor, solver::PoseEstimator& estimator,
                             const solver::CameraModel& camera, const solver::InstrumentModel& model,
                             const ImageView& image, bool extraction_ok, solver::SolveMode mode,
                             const solver::PoseVector& start, const GuidedOptions& options) noexcept {
  solver::CornerObservation observed;  // none when extraction failed
  if (extraction_ok) {
    corners_to_arrays(extractor.result(), observed.pixel, observed.visible);
  }
  const solver::Estimate first = estimator.estimate(observed, mode, start);
  if (first.quality != solver::EstimateQuality::None) {
    return rounds_from(extractor, estimator, camera, model, image, mode, first, options, false);
  }
  GuidedResult out;
  out.estimate = first;
  // Too few corners for the solver: a rough pose from the labelled regions,
  // kept only if the image fit confirms it (a round is kept).
  solver::PoseVector rough = start;
  if (options.from_regions && options.rounds > 0 && extractor.pose_from_regions(camera, model, rough).ok()) {
    solver::Estimate seed = first;
    seed.quality = solver::EstimateQuality::Degraded;
    seed.r = rough;
    const GuidedResult guided = rounds_from(extractor, estimator, camera, model, image, mode, seed, options, true);
    if (guided.rounds_kept > 0) {
      out = guided;
      out.from_regions = true;
    } else {
      out.fit = guided.fit;
    }
  }
  return out;
}

}  // namespace vision
}  // namespace tcpest
