#include "tcpest/loop/vision_pipeline.hpp"

#include <new>

namespace tcpest {
namespace loop {

namespace {
Status<StageError> from_vision(const Status<vision::VisionError>& s) noexcept {
  if (s.ok()) {
    return ok_status<StageError>();
  }
  return Status<StageError>::failure(StageError{static_cast<std::uint8_t>(s.error())});
}
}  // namespace

Result<std::unique_ptr<VisionPipeline>, vision::VisionError> VisionPipeline::create(
    const solver::CameraModel& camera, const solver::InstrumentModel& model, const vision::ColorModel& colors,
    int classify_step) noexcept {
  using R = Result<std::unique_ptr<VisionPipeline>, vision::VisionError>;
  std::unique_ptr<VisionPipeline> p(new (std::nothrow) VisionPipeline(camera, model));
  if (!p) {
    return R::failure(vision::VisionError::OutOfMemory);
  }
  vision::ExtractorConfig config;
  config.max_width = camera.width();
  config.max_height = camera.height();
  config.classify_step = classify_step;
  auto extractor = vision::FeatureExtractor::create(config, colors);
  if (!extractor.ok()) {
    return R::failure(extractor.error());
  }
  p->extractor_ = std::move(extractor.value());
  p->generic_ = vision::generic_priors(camera, model);
  return R::success(std::move(p));
}

Status<StageError> VisionPipeline::classify(const ImageView& image) noexcept {
  interpreted_ = false;
  return from_vision(extractor_->find_regions(image));
}

Status<StageError> VisionPipeline::interpret(PriorSource source, const solver::PoseVector& prior_r) noexcept {
  switch (source) {
    case PriorSource::kEncoder:
      priors_ = vision::model_priors(camera_, model_, prior_r);
      break;
    case PriorSource::kTemporal:
      if (!temporal_.priors(priors_)) {
        priors_ = vision::model_priors(camera_, model_, prior_r);
      }
      break;
    case PriorSource::kGeneric:
      priors_ = generic_;
      break;
  }
  const auto s = extractor_->interpret(priors_);
  interpreted_ = s.ok();
  return from_vision(s);
}

Status<StageError> VisionPipeline::borders(const ImageView& image) noexcept {
  return from_vision(extractor_->fit_borders(image));
}

Status<StageError> VisionPipeline::corners(const ImageView& image, solver::CornerObservation& out) noexcept {
  const auto s = extractor_->find_corners(image);
  if (s.ok()) {
    vision::corners_to_arrays(extractor_->result(), out.pixel, out.visible);
  }
  return from_vision(s);
}

bool VisionPipeline::refine(const ImageView& image, solver::PoseEstimator& estimator, solver::SolveMode mode,
                            const solver::PoseVector& start, solver::Estimate& estimate) noexcept {
  const vision::GuidedResult guided =
      vision::guided_rounds(*extractor_, estimator, camera_, model_, image, mode, estimate, start, guided_);
  degraded_by_fit_ = guided.disagreement_demoted;
  if (guided.rounds_kept == 0) {
    return false;
  }
  estimate = guided.estimate;
  return true;
}

void VisionPipeline::end_frame(bool success) noexcept {
  if (success && interpreted_) {
    temporal_.add(extractor_->result().interpretation);
  }
}

const char* VisionPipeline::describe(StageError error) const noexcept {
  return vision::to_string(static_cast<vision::VisionError>(error.code));
}

}  // namespace loop
}  // namespace tcpest
