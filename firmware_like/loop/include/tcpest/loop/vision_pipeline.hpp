// The loop's FeaturePipeline over tcpest_vision's FeatureExtractor (stages
// 1-4), with the loop's choice of prior turned into the stage-2 priors:
// encoder -> model priors at the encoders' configuration, temporal -> the
// last successful frames (model priors at the last estimate until two exist),
// generic -> the documented generic prior (computed once at start-up); and
// the model-guided rounds after the first solve (docs/vision.md).
#pragma once

#include <memory>

#include "tcpest/loop/ports.hpp"
#include "tcpest/vision/features.hpp"
#include "tcpest/vision/guided_estimate.hpp"

namespace tcpest {
namespace loop {

class VisionPipeline final : public FeaturePipeline {
 public:
  // Allocates the extractor for the camera's image size (start-up only).
  // classify_step: stage 1's grid (vision::ExtractorConfig::classify_step,
  // `loop.classify_step`; 0 = auto).
  static Result<std::unique_ptr<VisionPipeline>, vision::VisionError> create(const solver::CameraModel& camera,
                                                                            const solver::InstrumentModel& model,
                                                                            const vision::ColorModel& colors,
                                                                            int classify_step = 0) noexcept;

  const char* name() const noexcept override { return "vision"; }
  Status<StageError> classify(const ImageView& image) noexcept override;
  Status<StageError> interpret(PriorSource source, const solver::PoseVector& prior_r) noexcept override;
  Status<StageError> borders(const ImageView& image) noexcept override;
  Status<StageError> corners(const ImageView& image, solver::CornerObservation& out) noexcept override;
  bool refine(const ImageView& image, solver::PoseEstimator& estimator, solver::SolveMode mode,
              const solver::PoseVector& start, solver::Estimate& estimate) noexcept override;
  bool refine_degraded_by_fit() const noexcept override { return degraded_by_fit_; }
  vision::GuidedOptions& guided_options() noexcept { return guided_; }
  void end_frame(bool success) noexcept override;
  void drop_track() noexcept override { temporal_.reset(); }
  bool has_temporal_prior() const noexcept override { return temporal_.frames() >= vision::TemporalPriors::kMinFrames; }
  const char* describe(StageError error) const noexcept override;

  const vision::FeatureExtractor& extractor() const noexcept { return *extractor_; }

 private:
  VisionPipeline(const solver::CameraModel& camera, const solver::InstrumentModel& model) noexcept
      : camera_(camera), model_(model) {}
  const solver::CameraModel& camera_;
  const solver::InstrumentModel& model_;
  std::unique_ptr<vision::FeatureExtractor> extractor_;
  vision::MarkerPriors generic_{};
  vision::MarkerPriors priors_{};
  vision::TemporalPriors temporal_{};
  vision::GuidedOptions guided_{};
  bool interpreted_ = false;
  bool degraded_by_fit_ = false;  // the last refine()'s GuidedResult::disagreement_demoted
};

}  // namespace loop
}  // namespace tcpest
