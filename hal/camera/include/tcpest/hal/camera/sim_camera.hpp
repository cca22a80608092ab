// The simulated camera: frames drawn by a SceneRenderer (in tcpest, the
// synthetic endoscope of hal/render driven by a motion sequence; in tests,
// anything), stamped with the monotonic time at which they are delivered;
// their exact ground truth is kept beside them (TruthSource), for the tools
// and tests that score the loop, never handed to it.
#pragma once

#include <array>
#include <cstdint>

#include "tcpest/hal/camera/frame_source.hpp"

namespace tcpest {
namespace hal {

constexpr int kTruthCorners = 12;

// Exact ground truth of a simulated frame.
struct FrameTruth {
  bool valid = false;
  std::array<double, 3> tcp_mm{};              // camera frame
  std::array<double, 7> r{};                   // [x_ch, y_ch, psi, mu, lambda, phi, theta]
  std::array<std::array<double, 2>, kTruthCorners> corners_px{};
  std::array<bool, kTruthCorners> corner_visible{};
};

// A simulated source's truth of the frame it delivered last.
class TruthSource {
 public:
  TruthSource() noexcept = default;
  virtual ~TruthSource() = default;
  TruthSource(const TruthSource&) = delete;
  TruthSource& operator=(const TruthSource&) = delete;
  TruthSource(TruthSource&&) = delete;
  TruthSource& operator=(TruthSource&&) = delete;
  // Invalid before the first frame and after a failed one.
  virtual const FrameTruth& last_truth() const noexcept = 0;
};

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

class SimCamera final : public FrameSource, public TruthSource {
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
  const FrameTruth& last_truth() const noexcept override { return truth_; }

 private:
  SceneRenderer& renderer_;
  double rate_hz_;
  bool loop_;
  std::uint32_t next_ = 0U;
  std::uint32_t sequence_ = 0U;
  FrameTruth truth_{};
};

}  // namespace hal
}  // namespace tcpest
