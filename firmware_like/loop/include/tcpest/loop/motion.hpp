// The demo's motion: a smooth, deterministic joint trajectory of the
// instrument (insertion, rotation, bending as slow out-of-phase sinusoids
// inside the joint ranges), and a truth-only scene that projects it through
// the model (grey pixels, exact corners): the loop's tests run on it.
#pragma once

#include <cstdint>

#include "tcpest/hal/camera/sim_camera.hpp"
#include "tcpest/solver/camera.hpp"
#include "tcpest/solver/instrument.hpp"

namespace tcpest {
namespace loop {

struct MotionSequence {
  double rate_hz = 25.0;
  std::uint32_t frames = 250U;      // 10 s at 25 Hz
  double lambda_mid_mm = 24.0;
  double lambda_amp_mm = 6.0;
  double lambda_period_s = 7.0;
  double phi_amp_rad = 0.6;
  double phi_period_s = 9.0;
  double theta_mid_rad = 0.45;
  double theta_amp_rad = 0.35;
  double theta_period_s = 5.0;

  // The configuration at frame `index` (the channel at its nominal pose).
  solver::PoseVector pose(const solver::InstrumentGeometry& geometry, std::uint32_t index) const noexcept;
};

// Fills the truth of frame `index` from the model (corners present and inside the image are "visible").
void model_truth(const solver::CameraModel& camera, const solver::InstrumentModel& model, const solver::PoseVector& r,
                 hal::FrameTruth& truth) noexcept;

class ModelScene final : public hal::SceneRenderer {
 public:
  ModelScene(const solver::CameraModel& camera, const solver::InstrumentModel& model,
             const MotionSequence& motion) noexcept
      : camera_(camera), model_(model), motion_(motion) {}
  int width() const noexcept override { return camera_.width(); }
  int height() const noexcept override { return camera_.height(); }
  std::uint32_t frame_count() const noexcept override { return motion_.frames; }
  Status<hal::CameraError> render(std::uint32_t index, const MutableImageView& out,
                                  hal::FrameTruth& truth) noexcept override;
  // Frames in [from, to) come without truth (the oracle then finds nothing): tests of lost tracks.
  void blind(std::uint32_t from, std::uint32_t to) noexcept {
    blind_from_ = from;
    blind_to_ = to;
  }

 private:
  const solver::CameraModel& camera_;
  const solver::InstrumentModel& model_;
  MotionSequence motion_;
  std::uint32_t blind_from_ = 0U;
  std::uint32_t blind_to_ = 0U;
};

}  // namespace loop
}  // namespace tcpest
