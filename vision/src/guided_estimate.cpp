#include "tcpest/vision/guided_estimate.hpp"

#include <algorithm>
#include <array>

namespace tcpest {
namespace vision {

namespace {

constexpr int kMinSeedMarkers = 2;

GuidedResult rounds_from(FeatureExtractor& extractor, solver::PoseEstimator& estimator,
                         const solver::CameraModel& camera, const solver::InstrumentModel& model,
                         const ImageView& image, solver::SolveMode mode, const solver::Estimate& first,
                         const GuidedOptions& options, bool coarse_start) noexcept {
  GuidedResult out;
  out.estimate = first;
  const int rounds = std::min(std::max(options.rounds, 0), kMaxGuidedRounds);
  for (int round = 0; round < rounds && out.estimate.quality != solver::EstimateQuality::None; ++round) {
    const FeatureExtractor::CornerSnapshot previous = extractor.snapshot_corners();
    solver::PoseVector fitted = out.estimate.r;
    const bool fit_ok = extractor.fit_pose_to_image(image, camera, model, fitted, out.fit, coarse_start && round == 0).ok() &&
                        out.fit.rms_px <= options.max_fit_rms_px && out.fit.boundaries >= options.min_fit_boundaries &&
                        out.fit.silhouette_readings >= options.min_fit_silhouette_readings;
    if (!fit_ok) {
      break;
    }
    if (!extractor.refine_corners(image, camera, model, fitted, out.fit.streak_px).ok()) {
      extractor.restore_snapshot(previous);
      break;
    }
    solver::CornerObservation refined;
    corners_to_arrays(extractor.result(), refined.pixel, refined.visible);
    solver::Estimate again = estimator.estimate(refined, mode, fitted);
    if (again.quality == solver::EstimateQuality::None) {
      extractor.restore_snapshot(previous);
      break;
    }
    if (again.quality == solver::EstimateQuality::Valid &&
        (out.fit.boundary_run < options.min_valid_fit_boundaries ||
         out.fit.plain_silhouette_readings < options.min_valid_fit_silhouette_readings)) {
      again.quality = solver::EstimateQuality::Degraded;
    }
    out.estimate = again;
    out.rounds_kept = round + 1;
    out.fitted_r = fitted;
  }
  if (out.rounds_kept == 0) {
    extractor.restore_stage4_corners();
  }
  return out;
}

int rank(solver::EstimateQuality q) noexcept {
  switch (q) {
    case solver::EstimateQuality::Valid: return 2;
    case solver::EstimateQuality::Degraded: return 1;
    case solver::EstimateQuality::None: return 0;
  }
  return 0;
}

// The image's clear word for a candidate fit over the current one: it read
// at least as many boundaries and silhouette points, with a residual below
// prefer_fit_rms_ratio times the current's.
bool fit_clearly_better(const ImageFitSummary& fit, const ImageFitSummary& current,
                        const GuidedOptions& options) noexcept {
  return fit.rms_px < options.prefer_fit_rms_ratio * current.rms_px && fit.boundaries >= current.boundaries &&
         fit.silhouette_readings >= current.silhouette_readings;
}

// The rounds from a seed, from a coarse start; the result replaces `out`
// when better (else the extractor's corners are put back). True when it
// was kept.
bool try_seed(FeatureExtractor& extractor, solver::PoseEstimator& estimator, const solver::CameraModel& camera,
              const solver::InstrumentModel& model, const ImageView& image, solver::SolveMode mode,
              const solver::Estimate& first, const solver::PoseVector& seed_r, const GuidedOptions& options,
              GuidedResult& out) noexcept {
  solver::Estimate seed = first;
  seed.quality = solver::EstimateQuality::Degraded;
  seed.r = seed_r;
  const FeatureExtractor::CornerSnapshot kept = extractor.snapshot_corners();
  const GuidedResult tried = rounds_from(extractor, estimator, camera, model, image, mode, seed, options, true);
  if (replaces_result(tried, out, options)) {
    out = tried;
    return true;
  }
  extractor.restore_snapshot(kept);
  if (out.rounds_kept == 0) {
    out.fit = tried.fit;  // what the last fit tried saw, for the record
  }
  return false;
}

// The start's shaft fit when the start seed made it (the base-rim seed
// needs the same one: the same fit of the same image from the same pose).
struct StartShaft {
  bool fitted = false;  // fit_channel_to_shaft was run from `start`
  bool ok = false;      // ... and succeeded: `shafted` holds its pose
  solver::PoseVector shafted = solver::PoseVector::Zero();
};

// A seed moved onto the class image (fit_pose_to_classes): the channel's pose from
// the shaft first when it is seen (`channel_known`), so that the class fit
// need only find the joints. The seed's shaft may have lain outside the
// image (a short insertion at the CAD pose projects it beside the frame):
// from the class fit's pose it is looked for again, and the joints fitted
// once more with the channel it gives.
void move_onto_classes(FeatureExtractor& extractor, const solver::CameraModel& camera,
                       const solver::InstrumentModel& model, const ImageView& image, bool channel_known,
                       solver::PoseVector& seed_r) noexcept {
  solver::PoseVector moved = seed_r;
  double class_cost_px = 0.0;  // not used to judge: the image fit's test decides
  if (!extractor.fit_pose_to_classes(camera, model, moved, class_cost_px, channel_known).ok()) {
    return;
  }
  seed_r = moved;
  ShaftFitSummary shaft;
  solver::PoseVector shafted = seed_r;
  if (!channel_known && extractor.fit_channel_to_shaft(image, camera, model, shafted, shaft).ok() &&
      extractor.fit_pose_to_classes(camera, model, shafted, class_cost_px, true).ok()) {
    seed_r = shafted;
  }
}

// A seed as the start seed takes it: the channel's pose from the shaft
// (fit_channel_to_shaft), then moved onto the class image
// (fit_pose_to_classes, the channel held when the shaft fit succeeded).
// `shafted`: the seed after the shaft fit alone; true when that fit
// succeeded.
bool prepare_seed(FeatureExtractor& extractor, const solver::CameraModel& camera, const solver::InstrumentModel& model,
                  const ImageView& image, solver::PoseVector& seed_r, solver::PoseVector& shafted) noexcept {
  ShaftFitSummary shaft;
  const bool channel_known = extractor.fit_channel_to_shaft(image, camera, model, seed_r, shaft).ok();
  shafted = seed_r;
  move_onto_classes(extractor, camera, model, image, channel_known, seed_r);
  return channel_known;
}

// GuidedOptions::base_rim_seed. True when its result was kept in `out`.
// The start's shaft fit is taken from the start seed when it made one
// (`start_shaft`): the same fit of the same image from the same pose.
bool try_base_rim(FeatureExtractor& extractor, solver::PoseEstimator& estimator, const solver::CameraModel& camera,
                  const solver::InstrumentModel& model, const ImageView& image, solver::SolveMode mode,
                  const solver::PoseVector& start, const GuidedOptions& options, const StartShaft& start_shaft,
                  GuidedResult& out, StepSet& tried) noexcept {
  if (!options.base_rim_seed || options.rounds <= 0 || out.rounds_kept > 0 ||
      out.estimate.quality == solver::EstimateQuality::Valid || !start.allFinite()) {
    return false;
  }
  tried.add(StepKind::kBaseRimSeed);
  solver::PoseVector seed_r = start;
  bool channel_known = false;
  if (start_shaft.fitted) {
    channel_known = start_shaft.ok;
    seed_r = start_shaft.shafted;
  } else {
    ShaftFitSummary shaft;
    channel_known = extractor.fit_channel_to_shaft(image, camera, model, seed_r, shaft).ok();
  }
  if (!channel_known || !extractor.fit_insertion_to_base_rim(image, camera, model, seed_r).ok()) {
    return false;
  }
  const FeatureExtractor::CornerSnapshot kept = extractor.snapshot_corners();
  // The rim must be read again where the corners are taken (the base
  // measured), or the corners would be the start's guesses.
  if (!extractor.refine_corners(image, camera, model, seed_r).ok() || !extractor.result().boundary_measured[0]) {
    extractor.restore_snapshot(kept);
    return false;
  }
  solver::CornerObservation refined;
  corners_to_arrays(extractor.result(), refined.pixel, refined.visible);
  solver::Estimate estimate = estimator.estimate(refined, mode, seed_r);
  if (estimate.quality == solver::EstimateQuality::None) {
    extractor.restore_snapshot(kept);
    return false;
  }
  // Reported are the measured boundaries' corners only: the others are the
  // limb points of the start's bend, which the image did not confirm (the
  // solve had them as it had the start).
  std::array<Corner, kNumCorners> measured = extractor.result().corners;
  for (std::size_t j = 0U; j < static_cast<std::size_t>(kNumBoundaries); ++j) {
    if (!extractor.result().boundary_measured[j]) {
      measured[2U * j] = Corner{};
      measured[2U * j + 1U] = Corner{};
    }
  }
  extractor.restore_corners(measured);
  estimate.quality = solver::EstimateQuality::Degraded;
  out.estimate = estimate;
  out.rounds_kept = 1;
  out.fitted_r = seed_r;
  return true;
}

// GuidedOptions::max_valid_tcp_disagreement_mm, on the final result.
void check_against_fit(const solver::InstrumentModel& model, const GuidedOptions& options, GuidedResult& out) noexcept {
  if (out.rounds_kept == 0 || !out.estimate.r.allFinite() || !out.fitted_r.allFinite()) {
    return;
  }
  out.tried.add(StepKind::kFitAgreementCheck);
  out.tcp_disagreement_mm = (model.tcp(out.estimate.r) - model.tcp(out.fitted_r)).norm();
  if (options.max_valid_tcp_disagreement_mm > 0.0 && out.estimate.quality == solver::EstimateQuality::Valid &&
      out.tcp_disagreement_mm > options.max_valid_tcp_disagreement_mm) {
    out.estimate.quality = solver::EstimateQuality::Degraded;
    out.disagreement_demoted = true;
  }
}

// One frame's walk through the policy's rows (estimation_policy.hpp):
// what every row's step needs, and what the steps before it left.
struct PolicyWalk {
  FeatureExtractor& extractor;
  solver::PoseEstimator& estimator;
  const solver::CameraModel& camera;
  const solver::InstrumentModel& model;
  const ImageView& image;
  solver::SolveMode mode{};  // guided_rounds sets it; {} keeps the member initialised for any other use
  const solver::Estimate& first;
  const solver::PoseVector& start;
  const GuidedOptions& options;
  GuidedResult out{};
  StepSet tried{};
  StartShaft start_shaft{};

  void kept_from(StepKind kind) noexcept { out.produced_by = kind; }

  // kStartSeed: the start, its channel from the shaft, moved onto the
  // classes. It needs labelled markers: without them (stage 1 or 2
  // failed) the fit would read whatever edges lie where the seed puts the
  // instrument.
  void start_seed() noexcept {
    if (extractor.result().interpretation.found_count < kMinSeedMarkers || !start.allFinite()) {
      return;
    }
    solver::PoseVector seed_r = start;
    solver::PoseVector unmoved;  // the seed with its channel from the shaft, before the class fit
    const bool channel_known = prepare_seed(extractor, camera, model, image, seed_r, unmoved);
    start_shaft = StartShaft{true, channel_known, unmoved};
    tried.add(StepKind::kStartSeed);
    if (try_seed(extractor, estimator, camera, model, image, mode, first, seed_r, options, out)) {
      kept_from(StepKind::kStartSeed);
    }
  }

  void run(const PolicyStep& step) noexcept {
    if (options.rounds <= 0) {
      return;  // the paper's pipeline: stage 4's solve stands
    }
    switch (step.kind) {
      case StepKind::kStartSeed:
        if (out.estimate.quality != solver::EstimateQuality::Valid) {
          start_seed();
        }
        return;
      case StepKind::kBaseRimSeed:
        if (try_base_rim(extractor, estimator, camera, model, image, mode, start, options, start_shaft, out, tried)) {
          kept_from(StepKind::kBaseRimSeed);
        }
        return;
      default:
        return;  // the first and the last rows are run by guided_rounds and FrameEstimator
    }
  }
};

}  // namespace

// guided_estimate.hpp. A fallback result (always confirmed by an image fit)
// replaces the current one when the image speaks for it clearly, whatever the two qualities
// (the solve's quality can differ for the channel's penalty alone, eq. 8):
// the current one was not confirmed by a fit (stage 4's corners alone) and
// the candidate's fit has a valid estimate's support; or the candidate's
// fit read at least as much of the image with a residual below
// prefer_fit_rms_ratio times the current's (docs/vision.md). Otherwise when
// it is of a better quality; at the same quality, when the current one was
// not confirmed by a fit, or (longer_run_rms_ratio) its fit read the longer
// run of boundaries unless the shorter run's residual is clearly lower, or
// at the same run had a higher image-fit residual.
bool replaces_result(const GuidedResult& candidate, const GuidedResult& current, const GuidedOptions& options) noexcept {
  if (candidate.rounds_kept == 0) {
    return false;
  }
  const ImageFitSummary& fit = candidate.fit;
  if (options.prefer_fit_confirmed && current.rounds_kept == 0 && fit.boundary_run >= options.min_valid_fit_boundaries &&
      fit.silhouette_readings >= options.min_valid_fit_silhouette_readings) {
    return true;
  }
  if (current.rounds_kept > 0 && fit_clearly_better(fit, current.fit, options)) {
    return true;
  }
  const int a = rank(candidate.estimate.quality);
  const int b = rank(current.estimate.quality);
  if (a != b) {
    return a > b;
  }
  if (current.rounds_kept == 0) {
    return true;
  }
  const int run = candidate.fit.boundary_run;
  const int current_run = current.fit.boundary_run;
  const double ratio = options.longer_run_rms_ratio;
  if (ratio > 0.0 && run != current_run) {
    // The shorter run needs a clearly lower residual (either way round).
    return run > current_run ? ratio * candidate.fit.rms_px < current.fit.rms_px
                             : candidate.fit.rms_px < ratio * current.fit.rms_px;
  }
  return candidate.fit.rms_px < current.fit.rms_px;
}

GuidedResult guided_rounds(FeatureExtractor& extractor, solver::PoseEstimator& estimator,
                           const solver::CameraModel& camera, const solver::InstrumentModel& model,
                           const ImageView& image, solver::SolveMode mode, const solver::Estimate& first,
                           const solver::PoseVector& start, const GuidedOptions& options) noexcept {
  PolicyWalk walk{extractor, estimator, camera, model, image, mode, first, start, options};
  walk.out.estimate = first;
  if (first.quality != solver::EstimateQuality::None) {
    walk.out = rounds_from(extractor, estimator, camera, model, image, mode, first, options, false);
    if (walk.out.rounds_kept > 0) {
      walk.out.produced_by = StepKind::kGuidedRounds;
    }
    walk.tried.add(StepKind::kGuidedRounds);
  }
  // The rows between the guided rounds and the fit agreement check, in the
  // table's order; each tests its own condition (RunWhen) on the result so far.
  for (int i = static_cast<int>(StepKind::kGuidedRounds) + 1; i < static_cast<int>(StepKind::kFitAgreementCheck);
       ++i) {
    walk.run(kEstimationPolicy[static_cast<std::size_t>(i)]);
  }
  GuidedResult& out = walk.out;
  check_against_fit(model, options, out);
  StepSet tried = walk.tried;
  if (out.tried.has(StepKind::kFitAgreementCheck)) {
    tried.add(StepKind::kFitAgreementCheck);
  }
  out.tried = tried;
  return out;
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
  return guided_rounds(extractor, estimator, camera, model, image, mode, first, start, options);
}

}  // namespace vision
}  // namespace tcpest
