// A stand-in for the frame estimator in the loop's tests: the "detected"
// corners are the frame's ground-truth corners (from the simulated source's
// TruthSource, beside the loop),
// optionally with deterministic pseudo-random noise, solved by the solver's
// PoseEstimator from the frame's prior. It lets the loop, the solver and the
// CAN output be tested end to end without the feature extraction. Without
// truth, it finds nothing.
#pragma once

#include <cstdint>

#include "tcpest/hal/camera/sim_camera.hpp"
#include "tcpest/hal/clock/clock.hpp"
#include "tcpest/loop/ports.hpp"

namespace tcpest {
namespace loop {

class OraclePipeline final : public FeaturePipeline {
 public:
  // `config`: the solve's options and the encoders' check, as the estimator applies them.
  OraclePipeline(const solver::CameraModel& camera, const solver::InstrumentModel& model, double noise_px = 0.0,
                 const vision::EstimatorConfig& config = vision::EstimatorConfig{}) noexcept
      : model_(model), solver_(camera, model, config.solve), check_(config.encoder_check), noise_px_(noise_px) {}
  const char* name() const noexcept override { return "oracle"; }
  // Where the frames' truth comes from (nullptr: none, the oracle finds nothing).
  void set_truth_source(const hal::TruthSource* truth) noexcept { truth_ = truth; }
  vision::FrameEstimate estimate(const ImageView& image, const vision::FramePrior& prior,
                                 vision::StepObserver& observer) noexcept override;
  void drop_track() noexcept override { ++drops_; }
  void reset_appearance() noexcept override { ++appearance_resets_; }
  void set_encoder_check(const solver::EncoderCheck& check) noexcept { check_ = check; }
  int drops() const noexcept { return drops_; }
  int appearance_resets() const noexcept { return appearance_resets_; }

 private:
  const solver::InstrumentModel& model_;
  solver::PoseEstimator solver_;
  solver::EncoderCheck check_;
  double noise_px_;
  const hal::TruthSource* truth_ = nullptr;
  std::uint32_t sequence_ = 0U;  // frames estimated (the noise's key)
  int drops_ = 0;
  int appearance_resets_ = 0;
};

// The oracle with an estimate that takes simulated time (overruns and slips).
class SlowOracle final : public FeaturePipeline {
 public:
  SlowOracle(hal::SimulatedClock& clock, OraclePipeline& inner) noexcept : clock_(clock), inner_(inner) {}
  const char* name() const noexcept override { return "slow"; }
  vision::FrameEstimate estimate(const ImageView& image, const vision::FramePrior& prior,
                                 vision::StepObserver& observer) noexcept override {
    clock_.advance_ns(next_ns);
    return inner_.estimate(image, prior, observer);
  }
  void drop_track() noexcept override { inner_.drop_track(); }
  std::int64_t next_ns = 0;

 private:
  hal::SimulatedClock& clock_;
  OraclePipeline& inner_;
};

}  // namespace loop
}  // namespace tcpest
