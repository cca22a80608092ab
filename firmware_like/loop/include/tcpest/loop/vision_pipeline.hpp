// The loop's FeaturePipeline: tcpest_vision's FrameEstimator, created with
// the loop's estimator configuration (`loop:` section, vision::EstimatorConfig).
#pragma once

#include <memory>

#include "tcpest/loop/ports.hpp"
#include "tcpest/vision/frame_estimator.hpp"

namespace tcpest {
namespace loop {

class VisionPipeline final : public FeaturePipeline {
 public:
  // Allocates the estimator for the camera's image size (start-up only).
  static Result<std::unique_ptr<VisionPipeline>, vision::VisionError> create(
      const solver::CameraModel& camera, const solver::InstrumentModel& model, const vision::ColorModel& colors,
      const vision::EstimatorConfig& config = vision::EstimatorConfig{}) noexcept;

  const char* name() const noexcept override { return "vision"; }
  vision::FrameEstimate estimate(const ImageView& image, const vision::FramePrior& prior,
                                 vision::StepObserver& observer) noexcept override {
    return estimator_->estimate(image, prior, &observer);
  }
  void drop_track() noexcept override { estimator_->drop_track(); }
  void reset_appearance() noexcept override { estimator_->reset_appearance(); }

  const vision::FrameEstimator& estimator() const noexcept { return *estimator_; }
  const vision::FeatureExtractor& extractor() const noexcept { return estimator_->extractor(); }

 private:
  VisionPipeline() noexcept = default;
  std::unique_ptr<vision::FrameEstimator> estimator_;
};

}  // namespace loop
}  // namespace tcpest
