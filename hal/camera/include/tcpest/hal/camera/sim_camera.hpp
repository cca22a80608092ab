// The simulated camera: frames drawn by a SceneRenderer (in tcpest, the
// synthetic endoscope of hal/render driven by a motion sequence; in tests,
// anything), stamped with the monotonic time at which they are delivered and
// carrying their exact ground truth.
#pragma once

#include <cstdint>

#include "tcpest/hal/camera/frame_source.hpp"

namespace tcpest {
namespace hal {

class SceneRenderer {
 public:
  SceneRenderer() noexcept = default;
  virtual ~SceneRenderer() = default;
  SceneRenderer(const SceneRenderer&) = delete;
  SceneRenderer& operator=(const SceneRenderer&) = delete;
  SceneRenderer(SceneRenderer&&) = delete;
  SceneRenderer& operator=(SceneRenderer&&) = delete;

  virtual int width() const noexcept = 0;
  virtual int height() const noexcept = 0;
  // Frames in the sequence; 0 = endless.
  virtual std::uint32_t frame_count() const noexcept = 0;
  // Draws frame `index` (must not allocate) and its truth.
  virtual Status<CameraError> render(std::uint32_t index, const MutableImageView& out, FrameTruth& truth) noexcept = 0;
};

class SimCamera final : public FrameSource {
 public:
  SimCamera(SceneRenderer& renderer, double rate_hz, bool loop) noexcept
      : renderer_(renderer), rate_hz_(rate_hz), loop_(loop) {}

  const char* kind() const noexcept override { return "sim"; }
  int width() const noexcept override { return renderer_.width(); }
  int height() const noexcept override { return renderer_.height(); }
  double rate_hz() const noexcept override { return rate_hz_; }
  bool live() const noexcept override { return false; }
  Status<CameraError> acquire(const MutableImageView& out, FrameInfo& info) noexcept override;
  Status<CameraError> reopen() noexcept override;

 private:
  SceneRenderer& renderer_;
  double rate_hz_;
  bool loop_;
  std::uint32_t next_ = 0U;
  std::uint32_t sequence_ = 0U;
};

}  // namespace hal
}  // namespace tcpest
