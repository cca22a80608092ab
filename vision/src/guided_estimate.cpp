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

// What a row's result must meet, from its acceptance in the policy table.
SeedRule rule_of(StepKind kind, const solver::PoseVector& start) noexcept {
  SeedRule rule;
  switch (policy_step(kind).acceptance) {
    case Acceptance::kBetterNoFewerBoundaries:
      rule.no_fewer_boundaries = true;
      break;
    case Acceptance::kBetterNearerStart:
      rule.near_lambda_mm = start[solver::kLambda];
      break;
    case Acceptance::kClearlyBetter:
      rule.clearly_better = true;
      break;
    default:
      break;
  }
  return rule;
}

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

// The start's shaft fit when the start seed made it (the base-rim seed
// needs the same one: the same fit of the same image from the same pose).
struct StartShaft {
  bool fitted = false;  // fit_channel_to_shaft was run from `start`
  bool ok = false;      // ... and succeeded: `shafted` holds its pose
  solver::PoseVector shafted = solver::PoseVector::Zero();
};

// A fallback seed's pose from `start`; false when the options or the
// start leave it out. The unmoved start is not made here: it is the start
// seed's pose before its class fit.
bool fallback_seed(FeatureExtractor& extractor, const solver::CameraModel& camera,
                   const solver::InstrumentModel& model, const solver::PoseVector& start, const GuidedOptions& options,
                   StepKind kind, solver::PoseVector& seed_r) noexcept {
  seed_r = start;
  switch (kind) {
    case StepKind::kStartSeed:
      return options.start_seed && start.allFinite();
    case StepKind::kRegionsSeed:
      return options.from_regions && extractor.pose_from_regions(camera, model, seed_r).ok();
    case StepKind::kInsertionForthSeed:
    case StepKind::kInsertionBackSeed:
      if (!options.start_seed || !(options.insertion_seed_step_mm > 0.0) || !start.allFinite()) {
        return false;
      }
      seed_r[solver::kLambda] +=
          kind == StepKind::kInsertionForthSeed ? options.insertion_seed_step_mm : -options.insertion_seed_step_mm;
      return seed_r[solver::kLambda] > 0.0;
    case StepKind::kThetaUpSeed:
    case StepKind::kThetaDownSeed:
    case StepKind::kPhiUpSeed:
    case StepKind::kPhiDownSeed: {
      if (!options.start_seed || !(options.bend_seed_step_rad > 0.0) || !start.allFinite()) {
        return false;
      }
      const bool theta = kind == StepKind::kThetaUpSeed || kind == StepKind::kThetaDownSeed;
      const bool up = kind == StepKind::kThetaUpSeed || kind == StepKind::kPhiUpSeed;
      seed_r[theta ? solver::kTheta : solver::kPhi] += up ? options.bend_seed_step_rad : -options.bend_seed_step_rad;
      return true;
    }
    default:
      return false;
  }
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

// Two stripes along the tube the colours repeat (blue, yellow, blue): with
// an end of the tube hidden or smeared, a fit can hold the stripes two
// along from the true ones, the insertion off by 7.4 mm. When the result's
// insertion lies farther from the start's (the
// encoders', +/- 3 mm) than alias_lambda_tolerance_mm, the rounds are tried
// from the pose two stripes back towards it; that result is kept only if
// it is better (the rule above) and nearer to the start. From a fine start
// first (alias_fine_start): that seed has the result's shape, and the wide
// windows of a coarse start let the fit slide back onto the stripes it
// came from; then from a coarse start when the fine one was not kept, for a
// result whose shape is wrong too (docs/decisions/0030-alias-check.md).
// True when kept.
bool try_alias(FeatureExtractor& extractor, solver::PoseEstimator& estimator, const solver::CameraModel& camera,
               const solver::InstrumentModel& model, const ImageView& image, solver::SolveMode mode,
               const solver::Estimate& first, const solver::PoseVector& start, const GuidedOptions& options,
               GuidedResult& out, StepSet& tried) noexcept {
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
  tried.add(StepKind::kAliasCheck);
  SeedRule fine = rule_of(StepKind::kAliasCheck, start);
  fine.coarse_start = false;
  return (options.alias_fine_start &&
          try_seed(extractor, estimator, camera, model, image, mode, first, seed_r, options, out, fine)) ||
         try_seed(extractor, estimator, camera, model, image, mode, first, seed_r, options, out,
                  rule_of(StepKind::kAliasCheck, start));
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
  solver::SolveMode mode;
  const solver::Estimate& first;
  const solver::PoseVector& start;
  const GuidedOptions& options;
  GuidedResult out{};
  StepSet tried{};
  StartShaft start_shaft{};
  int seeds_tried = 0;
  bool start_seed_tried = false;           // this frame's start seed ran (the unmoved seed follows it)
  solver::PoseVector start_unmoved = solver::PoseVector::Zero();  // its pose before the class fit

  bool try_from(const solver::PoseVector& seed_r, const SeedRule& rule) noexcept {
    return try_seed(extractor, estimator, camera, model, image, mode, first, seed_r, options, out, rule);
  }
  void kept_from(StepKind kind) noexcept { out.produced_by = kind; }

  // kShaftRecheck: a valid result whose channel pose the shaft's silhouette
  // places elsewhere: the rounds again from the shaft's channel pose (the
  // joints kept), the better one kept. The solve's penalty holds the channel
  // near its CAD pose, and the image fit's narrow windows cannot move it far.
  void shaft_recheck() noexcept {
    if (!options.shaft_recheck) {
      return;
    }
    solver::PoseVector seed_r = out.estimate.r;
    ShaftFitSummary shaft;
    if (extractor.fit_channel_to_shaft(image, camera, model, seed_r, shaft).ok() &&
        (seed_r.head<2>() - out.estimate.r.head<2>()).norm() > options.shaft_recheck_min_mm) {
      tried.add(StepKind::kShaftRecheck);
      if (try_from(seed_r, rule_of(StepKind::kShaftRecheck, start))) {
        kept_from(StepKind::kShaftRecheck);
      }
    }
  }

  // kStartCheck: a valid result from stage 4's solve or the shaft re-check
  // may be a local minimum of the fit: the start seed's rounds are tried
  // too, the better result kept; only when no fit confirmed it closely.
  void start_check() noexcept {
    if (!options.valid_start_check || !start.allFinite() ||
        !(out.rounds_kept == 0 || out.fit.rms_px > options.valid_start_check_min_rms_px)) {
      return;
    }
    solver::PoseVector seed_r = start;
    solver::PoseVector shafted;
    static_cast<void>(prepare_seed(extractor, camera, model, image, options, seed_r, shafted));  // moved either way
    tried.add(StepKind::kStartCheck);
    if (try_from(seed_r, rule_of(StepKind::kStartCheck, start))) {
      kept_from(StepKind::kStartCheck);
    }
  }

  // The fallback seeds need labelled markers: without them (stage 1 or 2
  // failed) the fit would read whatever edges lie where the seed puts the
  // instrument. At most options.fallback_seeds per frame.
  bool seed_allowed() const noexcept {
    return extractor.result().interpretation.found_count >= kMinSeedMarkers && seeds_tried < options.fallback_seeds;
  }

  // kStartUnmovedSeed: the class fit can move a good start away (stripes an
  // occluder hides pull the visible ones along): the start seed's pose
  // before its class fit, right after the start seed.
  void unmoved_seed() noexcept {
    if (!start_seed_tried || !options.class_fit || !options.start_unmoved) {
      return;
    }
    ++seeds_tried;
    tried.add(StepKind::kStartUnmovedSeed);
    // No fewer boundaries read: a class-fitted seed may have read a smeared tube more fully.
    if (try_from(start_unmoved, rule_of(StepKind::kStartUnmovedSeed, start))) {
      kept_from(StepKind::kStartUnmovedSeed);
    }
  }

  // A fallback seed row other than the unmoved start.
  void fallback(StepKind kind) noexcept {
    solver::PoseVector seed_r;
    if (!fallback_seed(extractor, camera, model, start, options, kind, seed_r)) {
      return;
    }
    solver::PoseVector unmoved;  // the seed with its channel from the shaft, before the class fit
    const bool channel_known = prepare_seed(extractor, camera, model, image, options, seed_r, unmoved);
    if (kind == StepKind::kStartSeed) {
      start_seed_tried = true;
      start_unmoved = unmoved;
      if (options.shaft_fit) {
        start_shaft = StartShaft{true, channel_known, unmoved};
      }
    }
    ++seeds_tried;
    tried.add(kind);
    if (try_from(seed_r, rule_of(kind, start))) {
      kept_from(kind);
    }
  }

  void run(const PolicyStep& step) noexcept {
    const bool valid = out.estimate.quality == solver::EstimateQuality::Valid;
    if (options.rounds <= 0) {
      return;  // the paper's pipeline: stage 4's solve stands
    }
    switch (step.kind) {
      case StepKind::kShaftRecheck:
        if (valid) {
          shaft_recheck();
        }
        return;
      case StepKind::kStartCheck:
        if (valid) {
          start_check();
        }
        return;
      case StepKind::kStartUnmovedSeed:
        if (!valid && seed_allowed()) {
          unmoved_seed();
        }
        return;
      case StepKind::kAliasCheck:
        if (try_alias(extractor, estimator, camera, model, image, mode, first, start, options, out, tried)) {
          kept_from(StepKind::kAliasCheck);
        }
        return;
      case StepKind::kBaseRimSeed:
        if (try_base_rim(extractor, estimator, camera, model, image, mode, start, options, start_shaft, out, tried)) {
          kept_from(StepKind::kBaseRimSeed);
        }
        return;
      default:
        if (is_fallback_seed(step.kind) && !valid && seed_allowed()) {
          fallback(step.kind);
        }
        return;
    }
  }
};

}  // namespace

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
