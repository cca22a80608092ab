// What `tcpest estimate`, `tcpest evaluate` and `tcpest train-colors` share:
// reading image files (JPEG through hal/camera's decoder, binary PPM), loading
// the colour model, and one estimation step (extraction, then the solver) with
// the priors of a sequence.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "cli/setup.hpp"
#include "tcpest/hal/camera/jpeg_decoder.hpp"
#include "tcpest/render/renderer.hpp"
#include "tcpest/solver/pose_estimator.hpp"
#include "tcpest/vision/dense_estimate.hpp"
#include "tcpest/vision/features.hpp"
#include "tcpest/vision/frame_estimator.hpp"
#include "tcpest/vision/guided_estimate.hpp"
#include "tcpest/loop/config.hpp"

namespace tcpest {
namespace cli {

// A binary PGM (P5: 1 sample per pixel) or PPM (P6: 3 samples per pixel).
struct PnmInfo {
  int width = 0;
  int height = 0;
  int channels = 0;
};

// Reads a JPEG or binary PPM (P6) file into `pixels` (RGB24, resized to fit).
class ImageReader {
 public:
  bool init(int max_width, int max_height) noexcept;
  // False with a message in `error` (file missing, corrupt, too large ...).
  bool read(const char* path, std::vector<std::uint8_t>& pixels, ImageView& view, char* error,
            std::size_t error_capacity) noexcept;
  // The raw samples of an 8-bit binary PGM or PPM (`info.channels` per pixel,
  // rows packed), e.g. a hand-made mask; no JPEG. False with a message in
  // `error` (missing, not P5/P6, maxval not 255, too large, truncated).
  bool read_pnm(const char* path, std::vector<std::uint8_t>& samples, PnmInfo& info, char* error,
                std::size_t error_capacity) noexcept;

 private:
  hal::JpegDecoder decoder_;
  std::vector<std::uint8_t> file_;
  int max_width_ = 0;
  int max_height_ = 0;
};

// The sidecars (*.json) of one dataset directory (docs/dataset-format.md),
// their names sorted; false, after printing why (prefixed by `command`),
// when it cannot be read or holds none.
bool list_sidecars(const char* command, const std::string& dir, std::vector<std::string>& sidecars);

// --colors FILE or the built-in model. False after printing an error.
bool load_color_model(const char* command, const char* path, vision::ColorModel& out) noexcept;

struct StageTimes {
  double stage_us[4] = {0.0, 0.0, 0.0, 0.0};
  double solve_us = 0.0;
};

struct EstimateResult {
  solver::EstimateQuality status = solver::EstimateQuality::None;
  solver::PoseVector r = solver::PoseVector::Zero();
  solver::Vec3 tcp = solver::Vec3::Zero();
  // With a model-guided round kept (guided_rounds > 0): the TCP of the pose
  // the corners were read at (vision::GuidedResult::fitted_r), for
  // comparison with `tcp` (evaluate; docs/solver.md).
  solver::Vec3 fit_tcp = solver::Vec3::Zero();
  solver::SolveSummary summary{};
  int corners_rejected = 0;  // dropped as disagreeing with the model at the estimate
  int guided_rounds = 0;     // model-guided rounds kept (0: stage 4's corners)
  // The estimation policy's rows this frame ran, and the one whose result
  // was kept (vision/estimation_policy.hpp); a check that demoted the
  // estimate counts as producing it.
  vision::StepSet rows_tried{};
  vision::StepSet rows_produced{};
  bool encoder_disagrees = false;  // demoted one level: beyond the encoders' accuracy (solver::check_against_encoders)
  // Valid -> Degraded: the solve's TCP lay farther from fit_tcp than
  // vision::GuidedOptions::max_valid_tcp_disagreement_mm.
  bool fit_disagrees = false;
  // The dense stage ran on this frame (enabled, and dense_stage_applies),
  // and its result replaced the pipeline's (then dense_kept_quality).
  bool dense_ran = false;
  bool dense_kept = false;
  // The corners the pipeline measured on the image (measured_corner_count),
  // which the dense stage's rule asks for.
  int measured_corners = 0;
  bool extraction_ok = false;
  const char* extraction_error = "";
  // The motion-blur streak the kept image fit read (px, image; its sign is
  // arbitrary; zero: none read, ImageFitSummary::streak_px).
  solver::Vec2 streak_px = solver::Vec2::Zero();
  StageTimes times{};
  double total_us = 0.0;
};

// The offline commands' frame loop: the loop's own FrameEstimator and Track
// (vision/frame_estimator.hpp) with the loop's configuration, so that a
// sequence of images gives the estimates `tcpest run` sends; plus, on
// request, the offline dense stage (a research tool the loop never runs).
class EstimatePipeline {
 public:
  // `config`: the loop's configuration (its `loop:` section sets the
  // estimator and the track).
  bool init(const char* command, const ModelSetup& setup, const vision::ColorModel& colors,
            const loop::LoopConfig& config) noexcept;
  // One frame of a sequence. `prior_joints` (lambda, phi, theta) may be null.
  EstimateResult process(const ImageView& image, const double* prior_joints) noexcept;
  // A new sequence: the track and the temporal priors are forgotten (the
  // learned appearance is kept: images of one scene, as evaluate's lab sets).
  void reset_sequence() noexcept;
  // A new scene: what was learned of its appearance is forgotten too.
  void reset_appearance() noexcept;
  // A frame of the sequence that could not be read: it counts towards the
  // track's drop, as a dropped frame does in the loop.
  void frame_failed() noexcept;
  const vision::FeatureExtractor& extractor() const noexcept { return estimator_->extractor(); }
  const ModelSetup& setup() const noexcept { return setup_; }
  // The loop's configuration the pipeline was made with.
  const loop::LoopConfig& config() const noexcept { return config_; }
  // The dense stage on the frames the pipeline does not make valid or on
  // which it read a motion streak (off until enabled; offline only:
  // several seconds per frame). False: the options are out of range or its
  // buffers could not be allocated.
  bool enable_dense(const vision::DenseOptions& options) noexcept;
  // Overlay of the last frame (extraction, model at the estimate, TCP) into `pixels`.
  void draw_overlay(const EstimateResult& result, const MutableImageView& image) const noexcept;

 private:
  ModelSetup setup_{};
  loop::LoopConfig config_{};
  std::unique_ptr<vision::FrameEstimator> estimator_;
  std::unique_ptr<vision::Track> track_;
  // `start` holds the encoders' joints when `encoders_given`: the stage's
  // fits are then held within its box around them.
  void apply_dense(const ImageView& image, const vision::GuidedResult& guided, const solver::PoseVector& start,
                   bool encoders_given, solver::Estimate& estimate, EstimateResult& out) noexcept;
  std::unique_ptr<vision::DenseFit> dense_;
  vision::DenseOptions dense_options_{};
};

class Args;

// The pipeline of `tcpest COMMAND` from its arguments: the model setup
// (--calib, --config), the colour model (--colors), the solver mode
// (--fixed-model) and the guided rounds (--guided-rounds). False after
// printing an error, with exit_code
// kExitConfig for a file, kExitUsage for a value.
bool init_pipeline_from_args(const char* command, const Args& args, ModelSetup& setup, EstimatePipeline& pipeline,
                             int& exit_code) noexcept;

// Whether corner k of this frame is reported (estimate's JSON, evaluate's
// scores): found by stages 1-4, or re-measured around a pose by the
// model-guided rounds (Extraction::refined), which may follow a failed
// stage 3 or 4 and then give the corners the estimate was solved from.
// find_regions clears every corner at a frame's start, so neither is an
// older frame's.
bool corner_reported(const EstimateResult& result, const vision::Extraction& extraction, std::size_t k) noexcept;
// The corners the extraction measured on the image: stage 4's, or after a
// guided round those whose boundary arc was read (the others are the
// fitted pose's predictions, RefinerConfig::refine_predicted_confidence).
// The dense stage's rule asks for them (DenseOptions::max_measured_corners,
// max_measured_corners_valid).
int measured_corner_count(const vision::Extraction& extraction, const vision::ExtractorConfig& config) noexcept;
// Whether the dense stage runs on a frame: the pipeline's image fit read a
// motion streak of `streak_read_px` (DenseOptions::run_where_streak_read),
// or its estimate is not valid and it measured at most
// DenseOptions::max_measured_corners (by default every such frame) or the
// encoders contradict its estimate (DenseOptions::run_when_encoders_disagree),
// or its estimate is valid and it measured at most
// DenseOptions::max_measured_corners_valid.
bool dense_stage_applies(solver::EstimateQuality quality, int measured_corners, bool encoders_disagree,
                         double streak_read_px, const vision::DenseOptions& options) noexcept;
// The quality of an estimate the dense stage keeps (`solved`: the solve's
// from its corners; None stays None): degraded, but valid where it
// replaced a valid estimate, its solve is valid and its TCP moved at most
// DenseOptions::max_valid_tcp_change_mm from the replaced one's
// (`tcp_change_mm`; NaN: nothing replaced). The dense fit's corners have
// no validity rules of their own; two readings that agree do.
solver::EstimateQuality dense_kept_quality(solver::EstimateQuality replaced, solver::EstimateQuality solved,
                                           double tcp_change_mm, const vision::DenseOptions& options) noexcept;

// The JSON line of `tcpest estimate --json` (no newline).
void format_estimate_json(const char* image, const EstimateResult& result, const vision::Extraction& extraction,
                          char* out, std::size_t capacity) noexcept;

// `tcpest evaluate`'s frame success per hard case: a frame counts under
// each case it carries (the sidecar's hard_cases), or under "none".
struct HardCaseTally {
  std::array<int, render::kNumHardCases> frames{};
  std::array<int, render::kNumHardCases> successes{};
  int clear_frames = 0;     // frames without any hard case
  int clear_successes = 0;
  void add(std::uint32_t hard_cases, bool success) noexcept;
};
// "frame success by hard case: reflection 64.0 % of 75, ..., none 90.0 % of
// 10" (no newline; the cases without frames left out); an empty string when
// no frame carried a hard case.
void format_hard_case_tally(const HardCaseTally& tally, char* out, std::size_t capacity) noexcept;

// `tcpest evaluate`'s frame success by how many corners a frame shows: the
// success rule asks for 80 % of them, so a frame with 1-4 visible corners
// may miss none (docs/vision.md). Buckets 1-3, 4-5, 6-7, 8-12.
struct VisibleCornersTally {
  static constexpr int kBuckets = 4;
  std::array<int, kBuckets> frames{};
  std::array<int, kBuckets> successes{};
  void add(int visible, bool success) noexcept;  // a frame without a visible corner is not counted
};
// "frame success by visible corners: 1-3 35.5 % of 62, ..., 8-12 84.3 % of
// 1797" (no newline; empty buckets left out); an empty string when no
// frame was counted.
void format_visible_corners_tally(const VisibleCornersTally& tally, char* out, std::size_t capacity) noexcept;

// `tcpest evaluate`'s frame success by the truth's insertion lambda (the
// sidecar's r), in 5 mm bins centred on model.md's grid (10, 15, ..., 40
// mm; a lambda beyond the grid joins its end bin). Both ends of the range
// lose frames for their own reasons (at 10 mm the base at the image's edge
// and the shaft outside it, at 40 mm the shaft hiding most of the first
// stripe: docs/decisions/0046-evaluate-pools-seeds.md), which a pooled rate hides.
struct InsertionTally {
  static constexpr int kBins = 7;
  static constexpr double kFirstMm = 10.0;
  static constexpr double kStepMm = 5.0;
  std::array<int, kBins> frames{};
  std::array<int, kBins> successes{};
  void add(double lambda_mm, bool success) noexcept;  // a non-finite lambda is not counted
};
// "frame success by insertion (mm): 10 70.7 % of 335, ..., 40 74.9 % of
// 335" (no newline; empty bins left out); an empty string when no frame
// was counted.
void format_insertion_tally(const InsertionTally& tally, char* out, std::size_t capacity) noexcept;

}  // namespace cli
}  // namespace tcpest
