#include "tcpest/loop/vision_pipeline.hpp"

#include <new>

namespace tcpest {
namespace loop {

Result<std::unique_ptr<VisionPipeline>, vision::VisionError> VisionPipeline::create(
    const solver::CameraModel& camera, const solver::InstrumentModel& model, const vision::ColorModel& colors,
    const vision::EstimatorConfig& config) noexcept {
  using R = Result<std::unique_ptr<VisionPipeline>, vision::VisionError>;
  std::unique_ptr<VisionPipeline> p(new (std::nothrow) VisionPipeline());
  if (!p) {
    return R::failure(vision::VisionError::OutOfMemory);
  }
  auto estimator = vision::FrameEstimator::create(camera, model, colors, config);
  if (!estimator.ok()) {
    return R::failure(estimator.error());
  }
  p->estimator_ = std::move(estimator.value());
  return R::success(std::move(p));
}

}  // namespace loop
}  // namespace tcpest
