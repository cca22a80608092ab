// A V4L2 video capture device (the endoscope's frame grabber) with
// memory-mapped buffers: the driver fills a ring of kernel buffers, acquire()
// dequeues the newest filled one, converts it into the loop's RGB buffer and
// gives it back. Pixel formats: YUYV (packed 4:2:2), MJPEG (decoded by our
// JpegDecoder) and RGB24. Frame timestamps are the driver's (CLOCK_MONOTONIC
// for every current driver; V4L2_BUF_FLAG_TIMESTAMP_MONOTONIC is checked).
//
// All buffers are mapped at open(); acquire() makes no allocation. A device
// that disappears (ENODEV, EIO) gives kDeviceLost; reopen() tries again.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <memory>

#include "tcpest/hal/camera/frame_source.hpp"
#include "tcpest/hal/camera/jpeg_decoder.hpp"

namespace tcpest {
namespace hal {

enum class V4l2PixelFormat : std::uint8_t { kYuyv, kMjpeg, kRgb24 };
const char* to_string(V4l2PixelFormat format) noexcept;
// "yuyv", "mjpeg", "rgb24".
bool parse_v4l2_pixel_format(const char* text, V4l2PixelFormat& out) noexcept;

struct V4l2Options {
  int width = 720;
  int height = 576;
  V4l2PixelFormat format = V4l2PixelFormat::kYuyv;
  double rate_hz = 25.0;  // requested with VIDIOC_S_PARM (the driver may refuse: then its own rate)
  int buffers = 4;        // kernel buffers in the ring (2..kMaxBuffers)
  int timeout_ms = 200;   // acquire() waits at most this long for a frame (kNotReady after)
};

class V4l2Source final : public FrameSource {
 public:
  static constexpr int kMaxBuffers = 8;

  static Result<std::unique_ptr<V4l2Source>, CameraError> open(const char* device, const V4l2Options& options) noexcept;
  ~V4l2Source() override;
  V4l2Source(const V4l2Source&) = delete;
  V4l2Source& operator=(const V4l2Source&) = delete;
  V4l2Source(V4l2Source&&) = delete;
  V4l2Source& operator=(V4l2Source&&) = delete;

  const char* kind() const noexcept override { return "v4l2"; }
  int width() const noexcept override { return options_.width; }
  int height() const noexcept override { return options_.height; }
  double rate_hz() const noexcept override { return options_.rate_hz; }
  bool live() const noexcept override { return true; }
  Status<CameraError> acquire(const MutableImageView& out, FrameInfo& info) noexcept override;
  Status<CameraError> reopen() noexcept override;

  // Frames the driver dropped because we were late (sequence gaps).
  std::uint64_t dropped_by_driver() const noexcept { return dropped_; }

 private:
  V4l2Source() noexcept = default;
  Status<CameraError> start() noexcept;
  void stop() noexcept;

  char device_[256] = {};
  V4l2Options options_{};
  int fd_ = -1;
  struct Mapping {
    void* start = nullptr;
    std::size_t length = 0U;
  };
  std::array<Mapping, kMaxBuffers> mappings_{};
  int mapped_ = 0;
  std::size_t bytes_per_line_ = 0U;
  JpegDecoder decoder_;
  std::uint32_t sequence_ = 0U;
  std::uint32_t last_driver_sequence_ = 0U;
  bool have_driver_sequence_ = false;
  std::uint64_t dropped_ = 0U;
};

}  // namespace hal
}  // namespace tcpest
