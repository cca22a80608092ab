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
  // The fallback seed, when the result is not valid yet (no pose, or a
  // degraded one) and stage 2 labelled at least two markers: the image fit
  // is tried again from the start pose (the encoders' or the track's), from
  // a coarse start; its result is kept only if its fit passes the test
  // above and the re-solve gives a pose, and replaces the current one when
  // better: first when the image speaks for it clearly, whatever the
  // qualities (the current one not confirmed by a fit, the candidate's fit
  // with the support of a valid one; or its fit read at least as many
  // boundaries and silhouette points with a residual below
  // prefer_fit_rms_ratio times the current's); else valid over degraded; at
  // the same quality, a fit-confirmed one over stage 4's, then the lower fit
  // residual (docs/vision.md). Before the image fit, the seed's channel
  // pose is fitted to the shaft's silhouette
  // (FeatureExtractor::fit_channel_to_shaft), then the seed is moved onto
  // the class image (FeatureExtractor::fit_pose_to_classes, the channel
  // held when the shaft fit succeeded). One seed per frame, about 1-3 ms
  // at PAL.
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
  // After the seeds, a valid result is checked against its own image fit:
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
// the rounds from `first` when it has a pose, then, when the result is not
// valid, the start seed (`start`), then, with no fit kept and the result
// not valid, the base-rim seed (neither without a finite `start`). `first`
// may have no pose. On return the extractor's corners are those of the
// kept estimate (stage 4's if no round was kept).
GuidedResult guided_rounds(FeatureExtractor& extractor, solver::PoseEstimator& estimator,
                           const solver::CameraModel& camera, const solver::InstrumentModel& model,
                           const ImageView& image, solver::SolveMode mode, const solver::Estimate& first,
                           const solver::PoseVector& start, const GuidedOptions& options) noexcept;

// Whether a seed's result `candidate` replaces `current` (the comparison
// rule of GuidedOptions: prefer_fit_confirmed, prefer_fit_rms_ratio, the
// qualities, longer_run_rms_ratio, then the lower fit residual). Never
// without a round kept in `candidate`.
bool replaces_result(const GuidedResult& candidate, const GuidedResult& current,
                     const GuidedOptions& options) noexcept;

// The first solve and the rounds. `extraction_ok`: stages 1-4 succeeded
// (else no corners are used and the estimate is None).
GuidedResult guided_estimate(FeatureExtractor& extractor, solver::PoseEstimator& estimator,
                             const solver::CameraModel& camera, const solver::InstrumentModel& model,
                             const ImageView& image, bool extraction_ok, solver::SolveMode mode,
                             const solver::PoseVector& start, const GuidedOptions& options) noexcept;

}  // namespace vision
}  // namespace tcpest
