// The simulated camera's scenes: the synthetic endoscope (hal/render) drawing
// the instrument along the renderer's motion sequence (smooth joint motion,
// drifting play), with its exact ground truth and the encoder readings a
// robot would send for each frame (truth + bias + noise).
#pragma once

#include <cstdint>
#include <memory>

#include "tcpest/hal/camera/sim_camera.hpp"
#include "tcpest/loop/ports.hpp"
#include "tcpest/render/dataset.hpp"
#include "tcpest/render/renderer.hpp"

namespace tcpest {
namespace loop {

class RenderedScene final : public hal::SceneRenderer {
 public:
  // frames = 0: endless. Renderer tables are built here (start-up only).
  static Result<std::unique_ptr<RenderedScene>, render::RenderError> create(const solver::CameraModel& camera,
                                                                           const solver::InstrumentModel& model,
                                                                           std::uint64_t seed, double rate_hz,
                                                                           std::uint32_t frames) noexcept;

  int width() const noexcept override { return width_; }
  int height() const noexcept override { return height_; }
  std::uint32_t frame_count() const noexcept override { return frames_; }
  Status<hal::CameraError> render(std::uint32_t index, const MutableImageView& out,
                                  hal::FrameTruth& truth) noexcept override;
  // What the robot's encoders say at frame `index`.
  JointPrior encoder_reading(std::uint32_t index) const noexcept;

 private:
  RenderedScene(const solver::InstrumentGeometry& geometry, std::uint64_t seed, double rate_hz) noexcept
      : sequence_(geometry, seed, rate_hz), seed_(seed) {}
  std::unique_ptr<render::Renderer> renderer_;
  render::SequenceGenerator sequence_;
  std::uint64_t seed_;
  render::GroundTruth truth_{};
  int width_ = 0;
  int height_ = 0;
  std::uint32_t frames_ = 0U;
};

}  // namespace loop
}  // namespace tcpest
