// The frame estimator: one frame and its prior in, one estimate out. It is
// the only path from an image to a pose: the loop's cycle (`tcpest run`,
// `demo`, `bench`) and the offline commands (`estimate`, `evaluate`) all
// call it with the same configuration (EstimatorConfig, read from the
// `loop:` section of the configuration file; its defaults are declared
// here and nowhere else), so what `evaluate` scores is what the loop sends.
//
// The steps, in order (docs/estimation.md): stages 1-4 of the paper
// (regions, interpretation with the prior's marker priors, borders,
// corners), the first solve of eq. 8 from stage 4's corners, the
// model-guided rounds and fallback seeds (guided_rounds), and the encoders'
// check. The estimator never reads a clock: every step is bounded by counts
// (iterations, seeds, pixels); a StepObserver, when given, is told when each
// step ends so that the caller can time it against its budget.
//
// Allocation-free after create(); not thread-safe (one per loop).
#pragma once

#include <array>
#include <cstdint>
#include <memory>

#include "tcpest/common/result.hpp"
#include "tcpest/solver/pose_estimator.hpp"
#include "tcpest/vision/features.hpp"
#include "tcpest/vision/guided_estimate.hpp"

namespace tcpest {
namespace vision {

// Where a frame's prior comes from.
enum class PriorSource : std::uint8_t {
  kGeneric = 0,   // no track: the documented generic prior (nominal pose)
  kTemporal = 1,  // the last successful frames of the current track
  kEncoder = 2,   // the encoders' joints (a fresh, E2E-valid ENCODER_PRIOR, or a sidecar's prior)
};
constexpr int kNumPriorSources = 3;
const char* to_string(PriorSource source) noexcept;

struct FramePrior {
  PriorSource source = PriorSource::kGeneric;
  // The configuration the prior comes from (encoders / last estimate /
  // nominal): stage 2's marker priors and the solver's start.
  solver::PoseVector r = solver::PoseVector::Zero();
};

// The estimation's steps in the order they run (the loop's schedule gives
// each its time budget).
enum class EstimationStep : std::uint8_t {
  kClassify = 0,  // stage 1: pixel classes, regions
  kInterpret,     // stage 2: which region is which marker
  kBorders,       // stage 3: Bezier borders
  kCorners,       // stage 4: apparent corners
  kSolve,         // eq. 8 from stage 4's corners
  kRefine,        // model-guided rounds, fallback seeds, checks
};
constexpr int kNumEstimationSteps = 6;

// Told when each step ends (the caller's clock; never read by the estimator).
class StepObserver {
 public:
  StepObserver() noexcept = default;
  virtual ~StepObserver() = default;
  StepObserver(const StepObserver&) = delete;
  StepObserver& operator=(const StepObserver&) = delete;
  StepObserver(StepObserver&&) = delete;
  StepObserver& operator=(StepObserver&&) = delete;
  virtual void step_done(EstimationStep step) noexcept = 0;
};

// Everything that decides an estimate; the defaults are the shipped ones.
struct EstimatorConfig {
  int classify_step = 0;  // stage 1's grid: 0 = auto (2 from 4 PAL frames of pixels on), 1, 2
  solver::SolveMode solve_mode = solver::SolveMode::Adaptive;
  solver::EstimateOptions solve{};            // validity test and outlier rounds of every solve
  solver::EncoderCheck encoder_check{};       // an estimate beyond the encoders' accuracy loses one level
  GuidedOptions guided{};                     // model-guided rounds and fallback seeds
};
// Ranges of every field (the loader names the field; this is the last guard).
bool config_valid(const EstimatorConfig& config) noexcept;

// Where a reported corner comes from.
enum class CornerSource : std::uint8_t {
  kNone = 0,     // not reported
  kStage4,       // stage 4 (the paper's corners)
  kRemeasured,   // re-measured around a fitted pose (its boundary arc read)
  kPredicted,    // the fitted pose's prediction (its boundary arc not read)
};

struct EstimatedCorner {
  CornerSource source = CornerSource::kNone;
  Point pixel{};
  double confidence = 0.0;  // 0..1
};

// One frame's estimate; fixed size.
struct FrameEstimate {
  PriorSource prior = PriorSource::kGeneric;
  // The estimate of eq. 8 (quality, r, summary, corners rejected); r is
  // turned to the prior's equivalent joints (phi's turn, theta's sign).
  solver::Estimate estimate{};
  solver::Vec3 tcp_mm = solver::Vec3::Zero();  // valid when estimate.quality != None
  // Stages 1-4: the step that failed (kCorners + 1 = none failed) and its error.
  bool extraction_ok = false;
  EstimationStep failed_step = EstimationStep::kSolve;
  VisionError stage_error = VisionError::BadImage;
  int corners_detected = 0;  // stage 4's corners (0 when a stage failed)
  std::array<EstimatedCorner, kNumCorners> corners{};  // those of the kept estimate
  // The model-guided step: rounds kept (0: stage 4's solve stands), the
  // pose the kept corners were read at, its summary.
  GuidedResult guided{};
  bool encoder_disagrees = false;  // demoted one level by the encoders' check
  bool solved() const noexcept { return estimate.quality != solver::EstimateQuality::None; }
};

// What QUALITY reports (docs/can-protocol.md): the corners of the kept
// estimate measured in this frame's image (stage 4's or re-measured, not the
// model's prediction), and of those the ones the final solve used (0 when
// nothing was solved). Predicted corners help the solve but are no evidence
// from the image, so neither count includes them.
bool measured_in_image(CornerSource source) noexcept;
int corners_measured(const FrameEstimate& estimate) noexcept;
int measured_corners_used(const FrameEstimate& estimate) noexcept;

class FrameEstimator {
 public:
  // Allocates every buffer for frames up to max_width x max_height (0: the
  // camera's size). The marker colours come from the instrument's geometry.
  static Result<std::unique_ptr<FrameEstimator>, VisionError> create(const solver::CameraModel& camera,
                                                                    const solver::InstrumentModel& model,
                                                                    const ColorModel& colors,
                                                                    const EstimatorConfig& config,
                                                                    int max_width = 0, int max_height = 0) noexcept;
  ~FrameEstimator();
  FrameEstimator(const FrameEstimator&) = delete;
  FrameEstimator& operator=(const FrameEstimator&) = delete;
  FrameEstimator(FrameEstimator&&) = delete;
  FrameEstimator& operator=(FrameEstimator&&) = delete;

  // One frame. A solved estimate feeds the temporal priors.
  FrameEstimate estimate(const ImageView& image, const FramePrior& prior, StepObserver* observer) noexcept;
  // The track is dropped: forget the temporal priors.
  void drop_track() noexcept;
  // Forget what was learned of the scene's appearance (PartWidths): a
  // reset node, a new scene.
  void reset_appearance() noexcept;

  const EstimatorConfig& config() const noexcept { return config_; }
  const FeatureExtractor& extractor() const noexcept { return *extractor_; }
  // For the offline dense stage, which replaces the kept corners.
  FeatureExtractor& extractor() noexcept { return *extractor_; }
  solver::PoseEstimator& solver() noexcept { return *solver_; }
  const solver::CameraModel& camera() const noexcept { return camera_; }
  const solver::InstrumentModel& model() const noexcept { return model_; }

 private:
  FrameEstimator(const solver::CameraModel& camera, const solver::InstrumentModel& model,
                 const EstimatorConfig& config) noexcept;
  Status<VisionError> run_stages(const ImageView& image, const FramePrior& prior, StepObserver* observer,
                                 FrameEstimate& out) noexcept;
  void apply_encoder_check(const FramePrior& prior, solver::Estimate& estimate, FrameEstimate& out) const noexcept;
  void report_corners(FrameEstimate& out) const noexcept;

  const solver::CameraModel& camera_;
  const solver::InstrumentModel& model_;
  EstimatorConfig config_;
  std::unique_ptr<FeatureExtractor> extractor_;
  std::unique_ptr<solver::PoseEstimator> solver_;
  MarkerPriors generic_priors_{};
  MarkerPriors priors_{};
  TemporalPriors temporal_{};
};

// The track a sequence of frames follows: which prior each frame gets, and
// when the track is dropped. One for the loop and the offline commands, so
// that a sequence gives the same priors, and so the same estimates, in both.
class Track {
 public:
  // drop_after: consecutive failed frames (no pose, or a dropped frame)
  // before the track is dropped (>= 1).
  Track(const solver::InstrumentModel& model, int drop_after) noexcept;
  // The prior of the next frame: the encoders' joints when given (on the
  // track's channel pose, or the nominal one), else the track's last pose
  // while it is alive, else the generic prior.
  FramePrior choose(const double* encoder_joints) const noexcept;
  // After a frame's estimate. True when this frame dropped the track.
  bool update(const FrameEstimate& estimate) noexcept;
  // A frame that could not be estimated (corrupt, dropped). True when it dropped the track.
  bool frame_failed() noexcept;
  // Forget everything (an NMT reset, a new sequence).
  void reset() noexcept;

  bool alive() const noexcept { return alive_; }
  bool has_estimate() const noexcept { return has_estimate_; }
  const solver::PoseVector& last_r() const noexcept { return last_r_; }  // what a held frame repeats

 private:
  solver::PoseVector generic_r_ = solver::PoseVector::Zero();
  solver::PoseVector last_r_ = solver::PoseVector::Zero();
  int drop_after_ = 1;
  int failed_ = 0;
  bool alive_ = false;
  bool has_estimate_ = false;
};

// The generic prior's insertion (mm): the middle of model.md's range.
constexpr double kGenericLambdaMm = 25.0;

}  // namespace vision
}  // namespace tcpest
