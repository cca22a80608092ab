// The simulated camera as the loop runs it: the synthetic endoscope is far
// slower than a camera (about 0.2 s per PAL frame), so a sequence is rendered
// once at start-up (on a few threads), kept in memory as JPEG (as an MJPEG
// frame grabber would deliver it) with its ground truth and encoder readings,
// and replayed: acquire() decodes the next frame into the loop's buffer.
// Memory: about 60-100 KB per PAL frame; nothing allocated per frame.
#pragma once

#include <cstdint>
#include <memory>

#include "tcpest/hal/camera/frame_source.hpp"
#include "tcpest/hal/camera/jpeg_decoder.hpp"
#include "tcpest/hal/camera/sim_camera.hpp"
#include "tcpest/loop/ports.hpp"
#include "tcpest/solver/camera.hpp"
#include "tcpest/solver/instrument.hpp"

namespace tcpest {
namespace loop {

struct PrerenderOptions {
  std::uint32_t frames = 100U;  // 4 s at 25 Hz
  double rate_hz = 25.0;
  std::uint64_t seed = 7U;
  int jpeg_quality = 92;
  int threads = 2;
  bool loop = true;  // start again after the last frame
  // Called after each rendered frame (done, total), from the rendering threads; may be null.
  void (*progress)(std::uint32_t done, std::uint32_t total) = nullptr;
};

class PrerenderedSource final : public hal::FrameSource, public hal::TruthSource {
 public:
  static Result<std::unique_ptr<PrerenderedSource>, hal::CameraError> create(const solver::CameraModel& camera,
                                                                            const solver::InstrumentModel& model,
                                                                            const PrerenderOptions& options) noexcept;
  ~PrerenderedSource() override;
  PrerenderedSource(const PrerenderedSource&) = delete;
  PrerenderedSource& operator=(const PrerenderedSource&) = delete;
  PrerenderedSource(PrerenderedSource&&) = delete;
  PrerenderedSource& operator=(PrerenderedSource&&) = delete;

  const char* kind() const noexcept override { return "sim"; }
  int width() const noexcept override { return width_; }
  int height() const noexcept override { return height_; }
  double rate_hz() const noexcept override { return options_.rate_hz; }
  bool live() const noexcept override { return false; }
  Status<hal::CameraError> acquire(const MutableImageView& out, hal::FrameInfo& info) noexcept override;
  Status<hal::CameraError> reopen() noexcept override;
  const hal::FrameTruth& last_truth() const noexcept override { return last_truth_; }

  std::uint32_t frame_count() const noexcept { return options_.frames; }
  // Index of the frame the next acquire() delivers.
  std::uint32_t next_index() const noexcept { return next_; }
  const hal::FrameTruth& truth(std::uint32_t index) const noexcept;
  JointPrior encoder_reading(std::uint32_t index) const noexcept;
  const std::uint8_t* jpeg(std::uint32_t index, std::size_t& size) const noexcept;

  struct Frame;

 private:
  PrerenderedSource() noexcept = default;
  PrerenderOptions options_{};
  int width_ = 0;
  int height_ = 0;
  std::unique_ptr<Frame[]> frames_;
  hal::JpegDecoder decoder_;
  std::uint32_t next_ = 0U;
  std::uint32_t sequence_ = 0U;
  hal::FrameTruth last_truth_{};
};

}  // namespace loop
}  // namespace tcpest
