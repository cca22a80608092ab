// The dense stage (ours, after the model-guided rounds): the pose fitted to
// every pixel around the instrument (DenseFit) from several starts, the
// best kept by the fit's own cost. Starts: the poses the pipeline found
// (its image fit's, its solve's), and the start pose (the encoders' or the
// track's) with its insertion and bend moved by the encoders' accuracy,
// and the cheapest few of a screen of the start's channel moved and
// tilted and its insertion moved on a grid (the cost alone: the channel's
// play, which the encoders do not see, moves the tube by more than a fit's
// basin is wide; a tilt moves the bend's far end the most). Where the
// robot's encoders are given, every fit is held within their accuracy
// around their joints (EncoderBox).
// Each start is first fitted coarsely on a small work image; the best of
// those, and the pipeline's own poses as they are, are fitted finely on a
// larger one, and the lowest cost wins; optionally (off by default) the
// winner is fitted again from both sides of its softest direction
// (DenseFit::softest_step), and a lower cost replaces it. The corners
// are then the model's at that pose, those the image shows
// (DenseFit::corner_support).
// docs/vision.md, "The dense stage".
#pragma once

#include <array>

#include "tcpest/common/image.hpp"
#include "tcpest/solver/camera.hpp"
#include "tcpest/solver/instrument.hpp"
#include "tcpest/vision/dense_fit.hpp"
#include "tcpest/vision/features.hpp"

namespace tcpest {
namespace vision {

struct DenseOptions {
  int coarse_pixels = 6000;
  int fine_pixels = kDenseFineWorkPixels;  // the camera's own pixels for a PAL frame
  int coarse_iterations = 10;
  int fine_iterations = 15;
  int fine_candidates = 2;           // coarse results refined (besides the pipeline's poses)
  int coarse_smoothing = 0;          // binomial passes over the coarse work image (a wider basin)
  bool start_variants = true;        // the start moved by +/- lambda_step_mm and +/- bend_step_rad
  double lambda_step_mm = 2.0;
  double bend_step_rad = 0.2;
  bool channel_variants = false;     // the start's channel moved by +/- channel_step_mm in x and y
                                     // (off: more starts, about the same result on the hard sets)
  double channel_step_mm = 1.5;
  // A screen before the coarse fits: the cost alone (no iterations) at the
  // start with its channel moved by -1, 0, +1 screen_channel_mm in x and
  // y, tilted by -1, 0, +1 screen_tilt_rad in psi and mu (0: not tilted),
  // and its insertion by -2..2 screen_lambda_mm, and the screen_keep
  // cheapest of those fitted too (0: no screen).
  int screen_keep = 3;
  double screen_channel_mm = 2.5;
  double screen_tilt_rad = 0.07;
  double screen_lambda_mm = 1.5;
  // After the fine stage: its winner moved by -/+ its softest step
  // (DenseFit::softest_step: the model's corners moved by this many px
  // RMS), each fitted finely; a lower cost replaces the winner (0: no
  // such steps). Off: it lost as many frames as it gained, for a third
  // more time (docs/decisions/0038-dense-search.md).
  double softest_step_px = 0.0;
  // Where no streak comes in (the pipeline's image fit read none: it
  // failed on a blurred frame, or the frame is sharp), the fit cannot
  // start one (it frees the streak only from a length over 1 px). With
  // the streak screen, each coarse result kept for the fine stage takes
  // the cheapest of no streak and streak_screen_lengths lengths (from
  // streak_screen_min_px to streak_screen_max_px) in
  // streak_screen_directions directions over 180 deg, by the cost alone
  // at its pose (0 directions: no screen; docs/decisions/0039-dense-streak-screen.md).
  int streak_screen_directions = 6;
  int streak_screen_lengths = 3;
  double streak_screen_min_px = 5.0;
  double streak_screen_max_px = 13.0;
  double min_corner_support = 0.5;   // a corner is reported when the image around it is the rendering's
  // The stage runs on a result not valid where the pipeline measured at
  // most this many corners on the image (read, not predicted at its
  // pose); 12: on every frame not valid. With the corners blended with the
  // pipeline's (pipeline_corner_weight), its result is the better one
  // there too (docs/decisions/0040-dense-where-it-runs.md).
  int max_measured_corners = kNumCorners;
  // ... and on one the encoders contradict
  // (solver::disagrees_with_encoders; it would end none) whatever was
  // measured: it is not mostly right.
  bool run_when_encoders_disagree = true;
  // ... and on a valid result where the pipeline measured at most this
  // many corners (-1: never on a valid one): with more measured, the
  // pipeline's corners are the better ones (docs/decisions/0040-dense-where-it-runs.md).
  int max_measured_corners_valid = 7;
  // ... and where the pipeline's image fit read a motion streak (longer
  // than DenseFit::kMinStreakPx), whatever its estimate, valid too: along
  // a smeared border the pipeline's corners lie 1-3 px off on a fifth of
  // the valid blurred frames, and the dense fit models the streak at every
  // pixel (docs/decisions/0040-dense-where-it-runs.md).
  bool run_where_streak_read = true;
  // A valid estimate the stage replaces stays valid when the solve from
  // the stage's corners is valid and its TCP lies within this of the
  // replaced one's (mm): two readings of the frame that agree. Farther, or
  // 0, it is degraded, as everything else the stage keeps.
  double max_valid_tcp_change_mm = 2.0;
  // The stage's corners blended with the pipeline's own where both report
  // a corner (blend_pipeline_corners): within pipeline_corner_gate_px of
  // each other (px), the stage's corner moves pipeline_corner_weight of
  // the way to the pipeline's (0: the stage's corners as they are).
  double pipeline_corner_weight = 0.3;
  double pipeline_corner_gate_px = 3.0;
  // Where the robot's encoders are given, every fit holds the insertion
  // and the bend within these of their joints (EncoderBox; model.md's
  // coarse prior, the encoders' accuracy: the truth lies within it). On
  // views where the image leaves the bend open (the tube bent away from
  // the camera, its far stripes hidden behind its near ones; an occluder
  // over the middle), the cost's minimum otherwise lies beyond what the
  // encoders allow (docs/vision.md, "The dense stage"). 0: no box.
  double encoder_box_lambda_mm = 3.0;
  double encoder_box_angle_rad = 0.2;
};
// Ranges: work images of 256 to 2^20 pixels, 1 to 100 iterations, 0 to
// kMaxDenseFineCandidates fine candidates, 0 to 8 smoothing passes, steps
// finite and positive (lambda up to 10 mm, bends up to 1 rad, the channel
// up to 5 mm), the corner support within 0..1, max_measured_corners 0..12
// (max_measured_corners_valid -1..12),
// the screen's kept starts 0..kMaxDenseScreenKeep, its tilt 0..0.3 rad
// and its steps up to 5 mm, the softest step 0..20 px, the streak screen's
// directions 0..36 and lengths 1..8, from over 1 px to at most 20 px, the
// valid estimate's TCP change 0..10 mm, the pipeline corners' weight 0..1
// and their gate over 0 and at most 20 px, the encoders' box 0..10 mm and
// 0..1 rad.
bool dense_options_valid(const DenseOptions& options) noexcept;
constexpr int kMaxDenseSeeds = 2;
constexpr int kMaxDenseScreenKeep = 4;
constexpr int kMaxDenseStarts = kMaxDenseSeeds + 11 + kMaxDenseScreenKeep;
constexpr int kMaxDenseFineCandidates = 4;

struct DenseResult {
  bool ok = false;
  solver::PoseVector r = solver::PoseVector::Zero();
  solver::Vec2 streak_px = solver::Vec2::Zero();
  DenseFitSummary fit{};
  std::array<double, kNumCorners> support{};
  std::array<Corner, kNumCorners> corners{};  // the model's at r, found where supported
  int corner_count = 0;
};

// The stage's corners (`dense`, in place) blended with the pipeline's
// (`pipeline`: the corners it reports, measured on the image or predicted
// at its image fit's pose): a corner both report, within the gate of each
// other, moves the weight's share of the way to the pipeline's; any other
// stays as it is. The two are readings of one frame by different fits
// whose errors are only partly shared: on the hard sets' frames the stage
// ran on, the two corners' errors correlate by about 0.6, and the mean
// squared error of the blend is least at a weight of about 0.3 (0.29-0.31
// on either half of the seeds). Farther apart than the gate, one of them
// is wrong, and the stage's is the more often right (docs/vision.md, "The
// dense stage"). Non-finite pixels are left alone.
void blend_pipeline_corners(std::array<Corner, kNumCorners>& dense, const std::array<Corner, kNumCorners>& pipeline,
                            const DenseOptions& options) noexcept;

// `seeds`: the pipeline's poses (at most kMaxDenseSeeds; may be empty);
// `start`: the encoders' or the track's; `encoders`: the robot's encoders'
// joints (kLambda, kPhi, kTheta), or nullptr when not given (given, every
// fit is held within options' box around them); `streak_px`: the streak
// the pipeline read (zero: none). Allocation-free; bounded by the options.
DenseResult dense_estimate(DenseFit& fit, const solver::CameraModel& camera, const solver::InstrumentModel& model,
                           const ImageView& image, const solver::PoseVector* seeds, int seed_count,
                           const solver::PoseVector& start, const solver::PoseVector* encoders,
                           const solver::Vec2& streak_px, const DenseOptions& options) noexcept;

}  // namespace vision
}  // namespace tcpest
