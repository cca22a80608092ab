#include "tcpest/vision/guided_estimate.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

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

// A fallback result (always confirmed by an image fit) replaces the current
// one when the image speaks for it clearly, whatever the two qualities
// (the solve's quality can differ for the channel's penalty alone, eq. 8):
// the current one was not confirmed by a fit (stage 4's corners alone) and
// the candidate's fit has a valid estimate's support; or the candidate's
// fit read at least as much of the image with a residual below
// prefer_fit_rms_ratio times the current's (docs/vision.md). Otherwise when
// it is of a better quality; at the same quality, when the current one was
// not confirmed by a fit, or (longer_run_rms_ratio) its fit read the longer
// run of boundaries unless the shorter run's residual is clearly lower, or
// at the same run had a higher image-fit residual.
bool better(const GuidedResult& candidate, const GuidedResult& current, const GuidedOptions& options) noexcept {
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

// What a seed's result must also meet to replace the current one.
struct SeedRule {
  // With a finite value: its insertion lies nearer to this than out's.
  double near_lambda_mm = std::numeric_limits<double>::quiet_NaN();
  bool coarse_start = true;  // the fit's first iterations widened
  // Its fit read no fewer boundaries than out's (GuidedOptions::start_unmoved).
  bool no_fewer_boundaries = false;
  // Against a fit-confirmed out, the image's clear word
  // (fit_clearly_better), whatever the qualities; not a lower residual or a
  // better quality alone (GuidedOptions::bend_seed_step_rad).
  bool clearly_better = false;
};

// The rounds from a seed; the result replaces `out` when better and meets
// `rule` (else the extractor's corners are put back). True when it was kept.
bool try_seed(FeatureExtractor& extractor, solver::PoseEstimator& estimator, const solver::CameraModel& camera,
              const solver::InstrumentModel& model, const ImageView& image, solver::SolveMode mode,
              const solver::Estimate& first, const solver::PoseVector& seed_r, const GuidedOptions& options,
              GuidedResult& out, const SeedRule& rule = SeedRule{}) noexcept {
  solver::Estimate seed = first;
  seed.quality = solver::EstimateQuality::Degraded;
  seed.r = seed_r;
  const FeatureExtractor::CornerSnapshot kept = extractor.snapshot_corners();
  const GuidedResult tried =
      rounds_from(extractor, estimator, camera, model, image, mode, seed, options, rule.coarse_start);
  // Compared with a fit-confirmed result only: without a round kept, out's
  // pose is stage 4's solve or, with none, the start itself (nothing is
  // nearer to it).
  const bool nearer = std::isnan(rule.near_lambda_mm) || out.rounds_kept == 0 ||
                      std::fabs(tried.estimate.r[solver::kLambda] - rule.near_lambda_mm) <
                          std::fabs(out.estimate.r[solver::kLambda] - rule.near_lambda_mm);
  const bool read_enough =
      !rule.no_fewer_boundaries || out.rounds_kept == 0 || tried.fit.boundaries >= out.fit.boundaries;
  const bool clear = !rule.clearly_better || out.rounds_kept == 0 || fit_clearly_better(tried.fit, out.fit, options);
  if (nearer && read_enough && clear && better(tried, out, options)) {
    out = tried;
    return true;
  }
  extractor.restore_snapshot(kept);
  if (out.rounds_kept == 0) {
    out.fit = tried.fit;  // what the last fit tried saw, for the record
  }
  return false;
}

// Which of the start's variants the fallback seeds tried (GuidedResult's
// unmoved_tried, insertion_tried and bend_tried), and the start's shaft fit
// when the start seed made it (the base-rim seed needs the same one).
struct SeedsTried {
  bool unmoved = false;
  bool insertion = false;
  bool bend = false;
  bool start_shaft_fitted = false;  // fit_channel_to_shaft was run from `start`
  bool start_shaft_ok = false;      // ... and succeeded: start_shafted holds its pose
  solver::PoseVector start_shafted = solver::PoseVector::Zero();
};

// The fallback seeds' order (try_fallback_seeds).
constexpr int kStartSeed = 0;
constexpr int kRegionsSeed = 1;
constexpr int kInsertionForthSeed = 2;
constexpr int kInsertionBackSeed = 3;
constexpr int kBendSeed = 4;  // 4, 5: theta +, -; 6, 7: phi +, -
constexpr int kSeedIndices = 8;

// Fallback seed `seed_index`'s pose from `start` and the rule its result
// must meet (SeedRule); false when the options or the start leave it out.
bool fallback_seed(FeatureExtractor& extractor, const solver::CameraModel& camera,
                   const solver::InstrumentModel& model, const solver::PoseVector& start, const GuidedOptions& options,
                   int seed_index, solver::PoseVector& seed_r, SeedRule& rule) noexcept {
  seed_r = start;
  rule = SeedRule{};
  if (seed_index == kStartSeed) {
    return options.start_seed && start.allFinite();
  }
  if (seed_index == kRegionsSeed) {
    return options.from_regions && extractor.pose_from_regions(camera, model, seed_r).ok();
  }
  if (seed_index >= kBendSeed) {
    if (!options.start_seed || !(options.bend_seed_step_rad > 0.0) || !start.allFinite()) {
      return false;
    }
    const int bend_index = seed_index - kBendSeed;  // 0..3
    const int joint = bend_index < 2 ? solver::kTheta : solver::kPhi;
    seed_r[joint] += bend_index % 2 == 0 ? options.bend_seed_step_rad : -options.bend_seed_step_rad;
    rule.clearly_better = true;
    return true;
  }
  if (!options.start_seed || !(options.insertion_seed_step_mm > 0.0) || !start.allFinite()) {
    return false;
  }
  seed_r[solver::kLambda] +=
      seed_index == kInsertionForthSeed ? options.insertion_seed_step_mm : -options.insertion_seed_step_mm;
  rule.near_lambda_mm = start[solver::kLambda];
  return seed_r[solver::kLambda] > 0.0;
}

// A seed moved onto the class image (class_fit): the channel's pose from
// the shaft first when it is seen (`channel_known`), so that the class fit
// need only find the joints. The seed's shaft may have lain outside the
// image (a short insertion at the CAD pose projects it beside the frame):
// from the class fit's pose it is looked for again, and the joints fitted
// once more with the channel it gives.
void move_onto_classes(FeatureExtractor& extractor, const solver::CameraModel& camera,
                       const solver::InstrumentModel& model, const ImageView& image, const GuidedOptions& options,
                       bool channel_known, solver::PoseVector& seed_r) noexcept {
  solver::PoseVector moved = seed_r;
  double class_cost_px = 0.0;  // not used to judge: the image fit's test decides
  if (!extractor.fit_pose_to_classes(camera, model, moved, class_cost_px, channel_known).ok()) {
    return;
  }
  seed_r = moved;
  ShaftFitSummary shaft;
  solver::PoseVector shafted = seed_r;
  if (options.shaft_fit && !channel_known && extractor.fit_channel_to_shaft(image, camera, model, shafted, shaft).ok() &&
      extractor.fit_pose_to_classes(camera, model, shafted, class_cost_px, true).ok()) {
    seed_r = shafted;
  }
}

// A seed as the fallback seeds take it: the channel's pose from the shaft
// (shaft_fit), then moved onto the class image (class_fit). `shafted`: the
// seed after the shaft fit alone; true when that fit succeeded.
bool prepare_seed(FeatureExtractor& extractor, const solver::CameraModel& camera, const solver::InstrumentModel& model,
                  const ImageView& image, const GuidedOptions& options, solver::PoseVector& seed_r,
                  solver::PoseVector& shafted) noexcept {
  ShaftFitSummary shaft;
  const bool channel_known =
      options.shaft_fit && extractor.fit_channel_to_shaft(image, camera, model, seed_r, shaft).ok();
  shafted = seed_r;
  if (options.class_fit) {
    move_onto_classes(extractor, camera, model, image, options, channel_known, seed_r);
  }
  return channel_known;
}

// The fallback seeds (GuidedOptions), each kept in `out` when better.
SeedsTried try_fallback_seeds(FeatureExtractor& extractor, solver::PoseEstimator& estimator,
                              const solver::CameraModel& camera, const solver::InstrumentModel& model,
                              const ImageView& image, solver::SolveMode mode, const solver::Estimate& first,
                              const solver::PoseVector& start, const GuidedOptions& options,
                              GuidedResult& out) noexcept {
  // The fit from other seeds, each moved onto the class image
  // first (class_fit) and fitted from a coarse start. Seed 0: `start` (the
  // encoders' or the track's pose; start_seed), measured the more useful of
  // the two (docs/vision.md), then, when not valid, the same start without
  // its class fit (start_unmoved); seed 1: the rough pose of the labelled
  // regions (from_regions), when seed 0 did not give a valid estimate;
  // seeds 2 and 3: the start moved forth and back along the insertion
  // (insertion_seed_step_mm), their results kept against a fit-confirmed
  // one only when nearer to the start's insertion; seeds 4 to 7: the
  // start's theta, then its phi, moved forth and back (bend_seed_step_rad),
  // their results kept against a fit-confirmed one only when clearly
  // better.
  int seeds_tried = 0;
  SeedsTried tried{};
  for (int seed_index = 0; seed_index < kSeedIndices; ++seed_index) {
    if (out.estimate.quality == solver::EstimateQuality::Valid || seeds_tried >= options.fallback_seeds) {
      break;
    }
    solver::PoseVector seed_r;
    SeedRule rule;
    if (!fallback_seed(extractor, camera, model, start, options, seed_index, seed_r, rule)) {
      continue;
    }
    const bool insertion_seed = seed_index == kInsertionForthSeed || seed_index == kInsertionBackSeed;
    const bool bend_seed = seed_index >= kBendSeed;
    solver::PoseVector unmoved;  // the seed with its channel from the shaft, before the class fit
    const bool channel_known = prepare_seed(extractor, camera, model, image, options, seed_r, unmoved);
    if (seed_index == kStartSeed && options.shaft_fit) {
      tried.start_shaft_fitted = true;
      tried.start_shaft_ok = channel_known;
      tried.start_shafted = unmoved;
    }
    ++seeds_tried;
    tried.insertion = tried.insertion || insertion_seed;
    tried.bend = tried.bend || bend_seed;
    if (try_seed(extractor, estimator, camera, model, image, mode, first, seed_r, options, out, rule)) {
      out.from_start = seed_index == kStartSeed;
      out.from_regions = seed_index == kRegionsSeed;
      out.from_unmoved = false;
      out.from_insertion = insertion_seed;
      out.from_bend = bend_seed;
    }
    if (seed_index == kStartSeed && options.class_fit && options.start_unmoved &&
        out.estimate.quality != solver::EstimateQuality::Valid && seeds_tried < options.fallback_seeds) {
      ++seeds_tried;
      SeedRule unmoved_rule;
      unmoved_rule.no_fewer_boundaries = true;  // a class-fitted seed may have read a smeared tube more fully
      tried.unmoved = true;
      if (try_seed(extractor, estimator, camera, model, image, mode, first, unmoved, options, out, unmoved_rule)) {
        out.from_start = true;
        out.from_unmoved = true;
        out.from_regions = false;
        out.from_insertion = false;
        out.from_bend = false;
      }
    }
  }
  return tried;
}

// Two stripes along the tube the colours repeat (blue, yellow, blue): with
// an end of the tube hidden or smeared, a fit can hold the stripes two
// along from the true ones, the insertion off by 7.4 mm (hard frames 9, 14,
// 27). When the result's insertion lies farther from the start's (the
// encoders', +/- 3 mm) than alias_lambda_tolerance_mm, the rounds are tried
// from the pose two stripes back towards it; that result is kept only if
// it is better (the rule above) and nearer to the start. From a fine start
// first (alias_fine_start): that seed has the result's shape, and the wide
// windows of a coarse start let the fit slide back onto the stripes it
// came from (hard frame 27); then from a coarse start when the fine one was
// not kept (lab frame 14 needs it). True when kept.
bool try_alias(FeatureExtractor& extractor, solver::PoseEstimator& estimator, const solver::CameraModel& camera,
               const solver::InstrumentModel& model, const ImageView& image, solver::SolveMode mode,
               const solver::Estimate& first, const solver::PoseVector& start, const GuidedOptions& options,
               GuidedResult& out) noexcept {
  if (!options.alias_check || options.rounds <= 0 || out.rounds_kept == 0 || !start.allFinite()) {
    return false;
  }
  const double off_mm = out.estimate.r[solver::kLambda] - start[solver::kLambda];
  if (!(std::fabs(off_mm) > options.alias_lambda_tolerance_mm)) {
    return false;
  }
  const auto& boundaries = model.geometry().boundaries_mm;
  const double period_mm = boundaries[2] - boundaries[0];  // the colour pattern's period
  solver::PoseVector seed_r = out.estimate.r;
  seed_r[solver::kLambda] -= std::copysign(period_mm, off_mm);
  if (!(seed_r[solver::kLambda] > 0.0)) {
    return false;
  }
  const double near_mm = start[solver::kLambda];
  const bool kept =
      (options.alias_fine_start &&
       try_seed(extractor, estimator, camera, model, image, mode, first, seed_r, options, out,
                SeedRule{near_mm, false, false})) ||
      try_seed(extractor, estimator, camera, model, image, mode, first, seed_r, options, out,
               SeedRule{near_mm, true, false});
  out.alias_checked = true;
  out.from_alias = kept;
  return kept;
}

// GuidedOptions::base_rim_seed. True when its result was kept in `out`.
// The start's shaft fit is taken from the start seed when it made one
// (`tried`): the same fit of the same image from the same pose.
bool try_base_rim(FeatureExtractor& extractor, solver::PoseEstimator& estimator, const solver::CameraModel& camera,
                  const solver::InstrumentModel& model, const ImageView& image, solver::SolveMode mode,
                  const solver::PoseVector& start, const GuidedOptions& options, const SeedsTried& tried,
                  GuidedResult& out) noexcept {
  if (!options.base_rim_seed || options.rounds <= 0 || out.rounds_kept > 0 ||
      out.estimate.quality == solver::EstimateQuality::Valid || !start.allFinite()) {
    return false;
  }
  solver::PoseVector seed_r = start;
  bool channel_known = false;
  if (tried.start_shaft_fitted) {
    channel_known = tried.start_shaft_ok;
    seed_r = tried.start_shafted;
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
  out.from_base_rim = true;
  return true;
}

// GuidedOptions::max_valid_tcp_disagreement_mm, on the final result.
void check_against_fit(const solver::InstrumentModel& model, const GuidedOptions& options, GuidedResult& out) noexcept {
  if (out.rounds_kept == 0 || !out.estimate.r.allFinite() || !out.fitted_r.allFinite()) {
    return;
  }
  out.tcp_disagreement_mm = (model.tcp(out.estimate.r) - model.tcp(out.fitted_r)).norm();
  if (options.max_valid_tcp_disagreement_mm > 0.0 && out.estimate.quality == solver::EstimateQuality::Valid &&
      out.tcp_disagreement_mm > options.max_valid_tcp_disagreement_mm) {
    out.estimate.quality = solver::EstimateQuality::Degraded;
    out.disagreement_demoted = true;
  }
}

}  // namespace

GuidedResult guided_rounds(FeatureExtractor& extractor, solver::PoseEstimator& estimator,
                           const solver::CameraModel& camera, const solver::InstrumentModel& model,
                           const ImageView& image, solver::SolveMode mode, const solver::Estimate& first,
                           const solver::PoseVector& start, const GuidedOptions& options) noexcept {
  GuidedResult out;
  out.estimate = first;
  if (first.quality != solver::EstimateQuality::None) {
    out = rounds_from(extractor, estimator, camera, model, image, mode, first, options, false);
  }
  // A valid result whose channel pose the shaft's silhouette places
  // elsewhere: the rounds again from the shaft's channel pose (the joints
  // kept), the better one kept. The solve's penalty holds the channel near
  // its CAD pose, and the image fit's narrow windows cannot move it far;
  // the base boundary's corners, which are the fitted pose's, follow it.
  if (options.rounds > 0 && options.shaft_recheck && out.estimate.quality == solver::EstimateQuality::Valid) {
    solver::PoseVector seed_r = out.estimate.r;
    ShaftFitSummary shaft;
    if (extractor.fit_channel_to_shaft(image, camera, model, seed_r, shaft).ok() &&
        (seed_r.head<2>() - out.estimate.r.head<2>()).norm() > options.shaft_recheck_min_mm) {
      // Kept or not, `out` is then the better of the two.
      static_cast<void>(try_seed(extractor, estimator, camera, model, image, mode, first, seed_r, options, out));
      out.shaft_rechecked = true;
    }
  }
  // A valid result from stage 4's solve or the shaft re-check may be a
  // local minimum of the fit: the start seed's rounds are tried too, the
  // better result kept.
  if (options.rounds > 0 && options.valid_start_check && out.estimate.quality == solver::EstimateQuality::Valid &&
      start.allFinite() && (out.rounds_kept == 0 || out.fit.rms_px > options.valid_start_check_min_rms_px)) {
    solver::PoseVector seed_r = start;
    solver::PoseVector shafted;
    static_cast<void>(prepare_seed(extractor, camera, model, image, options, seed_r, shafted));  // moved either way
    out.start_checked = true;
    const bool rechecked = out.shaft_rechecked;
    if (try_seed(extractor, estimator, camera, model, image, mode, first, seed_r, options, out)) {
      out.from_start_check = true;
      out.start_checked = true;
      out.shaft_rechecked = rechecked;
    }
  }
  // Not valid yet: the fallback seeds. They need labelled markers: without
  // them (stage 1 or 2 failed) the fit would read whatever edges lie where
  // the seed puts the instrument.
  SeedsTried tried{};
  if (options.rounds > 0 && out.estimate.quality != solver::EstimateQuality::Valid &&
      extractor.result().interpretation.found_count >= kMinSeedMarkers) {
    tried = try_fallback_seeds(extractor, estimator, camera, model, image, mode, first, start, options, out);
  }
  static_cast<void>(try_alias(extractor, estimator, camera, model, image, mode, first, start, options, out));
  static_cast<void>(try_base_rim(extractor, estimator, camera, model, image, mode, start, options, tried, out));
  check_against_fit(model, options, out);
  // After every seed: a kept result's flags come from its own rounds.
  out.unmoved_tried = tried.unmoved;
  out.insertion_tried = tried.insertion;
  out.bend_tried = tried.bend;
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
