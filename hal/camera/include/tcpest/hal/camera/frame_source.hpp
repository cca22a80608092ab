// Frame sources: where the loop's images come from. Every source writes the
// next frame into a buffer the loop allocated at start-up (the configured image
// size) and says when the frame was taken; nothing allocates per frame, except
// libjpeg on progressive JPEGs (hal/camera/README.md).
//
//   JpegFileSource  a directory of JPEG files (sorted by name) or a list file
//   Y4mSource       YUV4MPEG2 raw video as ffmpeg writes it (the allocation-free replay path)
//   SimCamera       the simulated endoscope (a SceneRenderer: the renderer + a motion sequence)
//   V4l2Source      a V4L2 capture device with memory-mapped buffers (YUYV, MJPEG or RGB24)
#pragma once

#include <array>
#include <cstdint>

#include "tcpest/common/image.hpp"
#include "tcpest/common/result.hpp"
#include "tcpest/hal/camera/camera_error.hpp"

namespace tcpest {
namespace hal {

// What a source knows of a frame besides its pixels. No ground truth: that
// travels beside the frame in the simulation layer (sim_camera.hpp's
// TruthSource), never through the loop.
struct FrameInfo {
  std::int64_t timestamp_ns = 0;  // CLOCK_MONOTONIC time the frame was captured (replay: delivered)
  std::uint32_t sequence = 0U;    // the source's frame index (0, 1, ...; replay restarts count on)
};

class FrameSource {
 public:
  FrameSource() noexcept = default;
  virtual ~FrameSource() = default;
  FrameSource(const FrameSource&) = delete;
  FrameSource& operator=(const FrameSource&) = delete;
  FrameSource(FrameSource&&) = delete;
  FrameSource& operator=(FrameSource&&) = delete;

  virtual const char* kind() const noexcept = 0;  // "jpeg", "y4m", "sim", "v4l2"
  virtual int width() const noexcept = 0;
  virtual int height() const noexcept = 0;
  // The source's frame rate (frames per second); 0 if it does not say.
  virtual double rate_hz() const noexcept = 0;
  // True for a device that delivers frames in real time (acquire waits for
  // the next one); false for replay, which the loop paces itself.
  virtual bool live() const noexcept = 0;

  // The next frame into `out` (width() x height()). Errors: kEndOfStream at
  // the end of a replay, kNotReady when a live device has nothing within its
  // timeout, kDeviceLost when it has gone; a corrupt frame (kCorrupt,
  // kTruncated, kWrongSize) is one dropped frame and the next call goes on.
  virtual Status<CameraError> acquire(const MutableImageView& out, FrameInfo& info) noexcept = 0;

  // After kDeviceLost: try to open the device again (the loop calls this at a
  // slow rate while degraded). Replay sources start again from the first frame.
  virtual Status<CameraError> reopen() noexcept = 0;

  // Why the source ended before the end of its data (a damaged recording it
  // could not find its way through: acquire() then says kEndOfStream), or
  // nullptr when it did not. reopen() clears it.
  virtual const char* stop_reason() const noexcept { return nullptr; }
};

// Monotonic time for sources that stamp frames themselves (replay, sim).
std::int64_t monotonic_now_ns() noexcept;

}  // namespace hal
}  // namespace tcpest
