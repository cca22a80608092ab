// A stand-in for the vision stages: the "detected" corners are the frame's
// ground-truth corners (simulated camera only), optionally with
// deterministic pseudo-random noise. It lets the loop, the solver and the CAN
// output be tested and timed end to end before (or without) the real feature
// extraction, and gives a lower bound of the pipeline's error. It never runs
// on real images: without truth, it finds nothing.
#pragma once

#include <cstdint>

#include "tcpest/loop/ports.hpp"

namespace tcpest {
namespace loop {

class OraclePipeline final : public FeaturePipeline {
 public:
  explicit OraclePipeline(double noise_px = 0.0) noexcept : noise_px_(noise_px) {}
  const char* name() const noexcept override { return "oracle"; }
  void begin_frame(const hal::FrameInfo& info) noexcept override;
  Status<StageError> classify(const ImageView& image) noexcept override;
  Status<StageError> interpret(PriorSource source, const solver::PoseVector& prior_r) noexcept override;
  Status<StageError> borders(const ImageView& image) noexcept override;
  Status<StageError> corners(const ImageView& image, solver::CornerObservation& out) noexcept override;
  void end_frame(bool success) noexcept override;
  void drop_track() noexcept override { successes_ = 0; }
  bool has_temporal_prior() const noexcept override { return successes_ >= 2; }
  const char* describe(StageError error) const noexcept override;

 private:
  double noise_px_;
  hal::FrameTruth truth_{};
  std::uint32_t sequence_ = 0U;
  int successes_ = 0;
};

}  // namespace loop
}  // namespace tcpest
