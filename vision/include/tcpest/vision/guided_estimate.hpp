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

#include <limits>

#include "tcpest/solver/pose_estimator.hpp"
#include "tcpest/vision/estimation_policy.hpp"
#include "tcpest/vision/features.hpp"

namespace tcpest {
namespace vision {

struct GuidedOptions {
  int rounds = 1;                 // 0: stage 4's corners only (the paper's pipeline)
  // The image fit is trusted only with this much support: its robust RMS
  // residual, the boundaries whose arc it read, its silhouette readings.
  double max_fit_rms_px = 0.6;
  int min_fit_boundaries = 1;  // the fit's own rule asks 2, or 1 with the silhouette (refine_one_boundary_*)
  int min_fit_silhouette_readings = 0;  // none needed: see min_valid_fit_silhouette_readings
  // A fit that read fewer boundaries than this (an occluder or the image's
  // border hiding the rest) gives corners, but at most a Degraded estimate:
  // the unseen part of the tube, and the TCP with it, is held only by the
  // solve's penalty and the joints' start (docs/vision.md). Counted is the
  // run of consecutive colour boundaries read (ImageFitSummary::
  // boundary_run): an occluder's edge mimics the tip's change, and a fit
  // two stripes along reads a far boundary beyond a gap.
  int min_valid_fit_boundaries = 3;
  // Likewise a fit with fewer silhouette readings than this (of the 20 along
  // the striped section: an occluder or a smear hiding the rest): its
  // corners, at most a Degraded estimate (docs/vision.md). Counted are the
  // readings at the gradient peak's centre (plain_silhouette_readings): those
  // at the plateau's outer end under a streak (refine_streak_*) move the fit
  // but do not make it valid: under a streak they are not where the edge
  // is (docs/decisions/0012-consecutive-boundary-run.md).
  int min_valid_fit_silhouette_readings = 12;
  // Fallback seeds, when the result is not valid yet (no pose, or a degraded
  // one): the image fit is tried again from the start pose (`start_seed`:
  // the encoders' or the track's) and then from the rough pose of the
  // labelled regions (`from_regions`: pose_from_regions), each from a coarse
  // start; a result is kept only if its fit passes the test above and the
  // re-solve gives a pose, and replaces the current one when better: first
  // when the image speaks for it clearly, whatever the qualities (the
  // current one not confirmed by a fit, the candidate's fit with the
  // support of a valid one; or its fit read at least as many boundaries and
  // silhouette points with a residual below prefer_fit_rms_ratio times the
  // current's); else valid over degraded; at the same quality, a
  // fit-confirmed one over stage 4's, then the lower fit residual
  // (docs/vision.md). Bounded: at most `fallback_seeds` (0..9)
  // seeds per frame, only on frames not yet valid (each about 1-3 ms at PAL,
  // docs/vision.md).
  bool prefer_fit_confirmed = true;   // the first of those rules (false: off)
  double prefer_fit_rms_ratio = 0.7;  // the second (0: off)
  // At the same quality, two fit-confirmed results whose fits read runs of
  // boundaries of different lengths (ImageFitSummary::boundary_run): the
  // longer run is kept unless the shorter one's residual is below
  // longer_run_rms_ratio times the longer one's. A fit two stripes along,
  // or onto an occluder's edge, reads fewer boundaries and can settle on a
  // lower residual, and a lower residual alone would replace the true
  // stripes (docs/decisions/0028-longer-run.md). 0: off (the lower residual
  // alone).
  double longer_run_rms_ratio = 0.7;
  bool start_seed = true;
  bool from_regions = true;
  int fallback_seeds = 1;
  // Each fallback seed's channel pose is first fitted to the shaft's
  // silhouette (`shaft_fit`: FeatureExtractor::fit_channel_to_shaft), then
  // the seed is moved onto the class image (`class_fit`:
  // FeatureExtractor::fit_pose_to_classes, the channel held when the shaft
  // fit succeeded) before the image fit.
  bool shaft_fit = true;
  bool class_fit = true;
  // The class fit can also move a good start away: the samples of stripes
  // an occluder hides, far from every pixel of their colour, pull the
  // visible ones along the tube. So when the start seed's result is not
  // valid, the start (its channel from the shaft) is also tried as it is,
  // without the class fit (`start_unmoved`). It counts as one of the
  // `fallback_seeds`, tried second (the loop's 1 leaves it out; with 2
  // the regions' seed is not tried), and its result is kept only if
  // better (the rule above) and its fit read no fewer boundaries than the
  // current result's: the class fit's seed may have read a smeared tube
  // more fully (docs/vision.md, "Occluders").
  bool start_unmoved = true;
  // The encoders' insertion is known to +/- 3 mm (model.md), most of a
  // stripe (3.7 mm): from a start that far along, the coarse fit can settle
  // with every boundary one stripe from its own. So after the seeds above,
  // when still not valid, the start is tried moved by
  // +insertion_seed_step_mm and then -insertion_seed_step_mm along the
  // insertion (shaft fit and class fit as for the start), each counted as
  // one of the `fallback_seeds` (the 4th and 5th; a seed not available, such
  // as the regions' pose, leaves its count to the next); their result is
  // kept only if better (the rule above) and, against a fit-confirmed
  // result, its insertion nearer to the start's, so that a seed cannot
  // carry the fit two stripes along (0: off, and off with start_seed;
  // docs/vision.md, "Insertion seeds").
  double insertion_seed_step_mm = 2.0;
  // The encoders' bend is known to +/- 0.2 rad (model.md's coarse prior),
  // and from a start that far off the coarse fit can hold the tip's stripes
  // on the wrong side of the bend. So after the insertion seeds, when still
  // not valid, the start is tried with theta moved by +bend_seed_step_rad
  // and -bend_seed_step_rad, then phi likewise (shaft fit and class fit as
  // for the start), each counted as one of the `fallback_seeds` (the 6th to
  // the 9th). Their result is kept only if better (the rule above) and,
  // against a fit-confirmed result, clearly so: its fit read no fewer
  // boundaries and silhouette points with a residual below
  // prefer_fit_rms_ratio times the current's, whatever the qualities.
  // Four more seeds are four more chances for a lower residual at a wrong
  // pose, so the plain rule and a better quality alone are not enough (0:
  // off, and off with start_seed; docs/decisions/0026-bend-seeds.md).
  double bend_seed_step_rad = 0.2;
  // A valid result is checked against the shaft: when the shaft's fit moves
  // the channel's exit by more than `shaft_recheck_min_mm`, the rounds are
  // tried again from that channel pose (coarse start) and the better result
  // kept (the rule above). One shaft fit per valid frame, and at most one
  // more set of rounds.
  bool shaft_recheck = false;
  double shaft_recheck_min_mm = 0.3;
  // A valid result is also checked against the start: the rounds are tried
  // from the start seed (the channel from the shaft, then moved onto the
  // class image, as the first fallback seed) and that result kept when
  // better (the rule above). The rounds from stage 4's solve can settle
  // valid beside the image, the base's or the tip's corners 3-13 px off,
  // which no fallback seed would question (docs/vision.md, "A valid result
  // checked against the start"). Only when the result's image fit left a robust
  // RMS above valid_start_check_min_rms_px, or no fit confirmed it: a fit
  // that close to the image is rarely beside the tube, and checking every
  // valid frame costs a set of rounds on every frame
  // (docs/decisions/0031-valid-start-check.md). One shaft fit, one class
  // fit and one more set of rounds per frame checked.
  bool valid_start_check = false;
  double valid_start_check_min_rms_px = 0.2;
  // Two stripes along the tube the colours repeat: a fit-confirmed result
  // whose insertion lies more than `alias_lambda_tolerance_mm` from the
  // start's (the encoders' accuracy is +/- 3 mm, model.md) is tried again
  // from the pose two stripes (7.4 mm) back towards the start, and that
  // result kept when better (the rule above) and nearer to the start. At
  // most two more sets of rounds per frame (docs/vision.md).
  bool alias_check = false;
  double alias_lambda_tolerance_mm = 3.0;
  // The alias seed keeps the result's shape, so it is tried first from a
  // fine start, whose narrow windows hold the stripes where the period
  // put them, and from a coarse start only when that was not kept (false:
  // the coarse start alone).
  bool alias_fine_start = true;
  // When no image fit was kept and the result is not valid (stage 4's
  // Degraded solve, or none; a valid one stays, as it stops the seeds): a
  // tube seen end-on behind the shaft, one stripe showing, gives the image
  // fit too little to hold. Its base corners need only the channel's pose
  // and the insertion: the channel from the shaft (fit_channel_to_shaft,
  // from `start`), the insertion from the base's rim
  // (FeatureExtractor::fit_insertion_to_base_rim), the bend the start's;
  // then the corners re-measured there (refine_corners, the rim read
  // again) and the pose solved from them, at most Degraded (the tube
  // beyond the first boundary is not seen). Kept when the solve gives a
  // pose; only the measured boundaries' corners are then reported. One
  // shaft fit (none when the start seed fitted the start's), at most
  // 2 * kMaxRimScanSteps + 1 rim reads, one refinement and one solve
  // (docs/vision.md, "The tube seen end-on").
  bool base_rim_seed = true;
  // After every seed, a valid result is checked against its own image fit:
  // when the TCP of the solve of eq. 8 lies more than
  // max_valid_tcp_disagreement_mm from the TCP of the pose the corners were
  // read at (GuidedResult::fitted_r), the estimate is Degraded. The solve's
  // penalty pulls the channel towards its CAD pose and the joints make up
  // for it (docs/solver.md, "The image fit's pose and the TCP"): with a
  // play of 1.5-2 sd the solve lands 3-7 mm off at the TCP, its corner
  // residual still under the solve's validity limit, while the fitted pose
  // lies within 0.1-0.7 mm. Only the status changes: the pose, the TCP and
  // the corners stay (docs/vision.md, "A valid solve that its image fit
  // contradicts"). 0: not checked. Checked only when a round was kept:
  // there is no fitted pose otherwise.
  double max_valid_tcp_disagreement_mm = 2.0;
};
constexpr int kMaxGuidedRounds = 4;
constexpr int kMaxFallbackSeeds = 9;

struct GuidedResult {
  solver::Estimate estimate{};
  int rounds_kept = 0;            // rounds whose corners and pose were kept
  // With a round kept: the pose the kept corners were read at (the image
  // fit's, or the base-rim seed's), before the solve of eq. 8 re-estimates
  // r from those corners under the channel's penalty (docs/solver.md,
  // "The image fit's pose and the TCP").
  solver::PoseVector fitted_r = solver::PoseVector::Zero();
  ImageFitSummary fit{};          // of the last fit tried
  // The policy row whose result was kept (kStage4Solve: none replaced the
  // first solve; kGuidedRounds: the rounds from it), and every row tried on
  // this frame (estimation_policy.hpp).
  StepKind produced_by = StepKind::kStage4Solve;
  StepSet tried{};
  // With a round kept: the distance (mm) between the TCP of the estimate's
  // r and that of fitted_r; NaN without one.
  double tcp_disagreement_mm = std::numeric_limits<double>::quiet_NaN();
  bool disagreement_demoted = false;  // Valid -> Degraded by max_valid_tcp_disagreement_mm
};

// Everything after the first solve (the loop times it as its own step):
// the rounds from `first` when it has a pose, then, while the result is not
// valid, the fallback seeds (the regions' rough pose, `start`), then the
// alias check against `start`'s insertion, then, with no fit kept and the
// result not valid, the base-rim seed. `first` may have no pose. On return
// the extractor's corners are those of the kept estimate (stage 4's if no
// round was kept).
GuidedResult guided_rounds(FeatureExtractor& extractor, solver::PoseEstimator& estimator,
                           const solver::CameraModel& camera, const solver::InstrumentModel& model,
                           const ImageView& image, solver::SolveMode mode, const solver::Estimate& first,
                           const solver::PoseVector& start, const GuidedOptions& options) noexcept;

// The first solve and the rounds. `extraction_ok`: stages 1-4 succeeded
// (else no corners are used and the estimate is None).
GuidedResult guided_estimate(FeatureExtractor& extractor, solver::PoseEstimator& estimator,
                             const solver::CameraModel& camera, const solver::InstrumentModel& model,
                             const ImageView& image, bool extraction_ok, solver::SolveMode mode,
                             const solver::PoseVector& start, const GuidedOptions& options) noexcept;

}  // namespace vision
}  // namespace tcpest
