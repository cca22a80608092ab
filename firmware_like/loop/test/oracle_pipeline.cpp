#include "oracle_pipeline.hpp"

#include "tcpest/common/splitmix64.hpp"

namespace tcpest {
namespace loop {

namespace {
// A small deterministic hash to [-1, 1] (splitmix64).
double unit_noise(std::uint64_t key) noexcept {
  return static_cast<double>(splitmix64(key) >> 11U) * (2.0 / 9007199254740992.0) - 1.0;
}
}  // namespace

vision::FrameEstimate OraclePipeline::estimate(const ImageView& image, const vision::FramePrior& prior,
                                               vision::StepObserver& observer) noexcept {
  static_cast<void>(image);
  vision::FrameEstimate out;
  out.prior = prior.source;
  solver::CornerObservation corners;
  const hal::FrameTruth truth = truth_ != nullptr ? truth_->last_truth() : hal::FrameTruth{};
  const std::uint32_t sequence = sequence_++;
  if (truth.valid) {
    for (int k = 0; k < solver::kNumCorners; ++k) {
      const auto i = static_cast<std::size_t>(k);
      corners.visible[i] = truth.corner_visible[i];
      const std::uint64_t key = (static_cast<std::uint64_t>(sequence) << 8U) + static_cast<std::uint64_t>(2 * k);
      corners.pixel[i] = solver::Vec2(truth.corners_px[i][0] + noise_px_ * unit_noise(key),
                                      truth.corners_px[i][1] + noise_px_ * unit_noise(key + 1U));
      if (corners.visible[i]) {  // reported as stage 4's, as the real pipeline does without guided rounds
        out.corners[i].source = vision::CornerSource::kStage4;
        out.corners[i].pixel = vision::Point{corners.pixel[i].x(), corners.pixel[i].y()};
        out.corners[i].confidence = 1.0;
      }
    }
    out.extraction_ok = true;
    out.corners_detected = corners.count_visible();
  } else {
    out.failed_step = vision::EstimationStep::kClassify;
    out.stage_error = vision::VisionError::NoInstrument;
  }
  observer.step_done(vision::EstimationStep::kClassify);
  observer.step_done(vision::EstimationStep::kInterpret);
  observer.step_done(vision::EstimationStep::kBorders);
  observer.step_done(vision::EstimationStep::kCorners);
  out.estimate = solver_.estimate(corners, solver::SolveMode::Adaptive, prior.r);
  out.encoder_disagrees = prior.source == vision::PriorSource::kEncoder &&
                          solver::check_against_encoders(out.estimate, prior.r, check_);
  out.estimate.r = solver::nearest_equivalent_joints(out.estimate.r, prior.r);
  if (out.solved()) {
    out.tcp_mm = model_.tcp(out.estimate.r);
  }
  observer.step_done(vision::EstimationStep::kSolve);
  observer.step_done(vision::EstimationStep::kRefine);
  return out;
}

}  // namespace loop
}  // namespace tcpest
