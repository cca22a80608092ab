#include "tcpest/hal/camera/v4l2_source.hpp"

#include <fcntl.h>
#include <linux/videodev2.h>
#include <poll.h>
#include <sys/ioctl.h>
#include <sys/mman.h>
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <new>

#include "tcpest/hal/camera/pixel_formats.hpp"

namespace tcpest {
namespace hal {

namespace {

CameraError from_errno(int error) noexcept {
  switch (error) {
    case ENOENT:
      return CameraError::kNotFound;
    case ENODEV:
    case ENXIO:
    case EIO:
      return CameraError::kDeviceLost;
    case ENOTTY:
    case EINVAL:
      return CameraError::kUnsupported;
    case ENOMEM:
      return CameraError::kOutOfMemory;
    default:
      return CameraError::kIo;
  }
}

// ioctl, retried on EINTR (a bounded number of times).
int xioctl(int fd, unsigned long request, void* arg) noexcept {
  int rc = -1;
  for (int attempt = 0; attempt < 16; ++attempt) {
    rc = ::ioctl(fd, request, arg);  // NOLINT(cppcoreguidelines-pro-type-vararg): the V4L2 interface is ioctl
    if (rc >= 0 || errno != EINTR) {
      break;
    }
  }
  return rc;
}

std::uint32_t fourcc(V4l2PixelFormat format) noexcept {
  switch (format) {
    case V4l2PixelFormat::kYuyv:
      return V4L2_PIX_FMT_YUYV;
    case V4l2PixelFormat::kMjpeg:
      return V4L2_PIX_FMT_MJPEG;
    case V4l2PixelFormat::kRgb24:
      return V4L2_PIX_FMT_RGB24;
  }
  return V4L2_PIX_FMT_YUYV;
}

}  // namespace

const char* to_string(V4l2PixelFormat format) noexcept {
  switch (format) {
    case V4l2PixelFormat::kYuyv:
      return "yuyv";
    case V4l2PixelFormat::kMjpeg:
      return "mjpeg";
    case V4l2PixelFormat::kRgb24:
      return "rgb24";
  }
  return "?";
}

bool parse_v4l2_pixel_format(const char* text, V4l2PixelFormat& out) noexcept {
  if (text == nullptr) {
    return false;
  }
  if (std::strcmp(text, "yuyv") == 0) {
    out = V4l2PixelFormat::kYuyv;
  } else if (std::strcmp(text, "mjpeg") == 0) {
    out = V4l2PixelFormat::kMjpeg;
  } else if (std::strcmp(text, "rgb24") == 0) {
    out = V4l2PixelFormat::kRgb24;
  } else {
    return false;
  }
  return true;
}

Result<std::unique_ptr<V4l2Source>, CameraError> V4l2Source::open(const char* device,
                                                                const V4l2Options& options) noexcept {
  using R = Result<std::unique_ptr<V4l2Source>, CameraError>;
  if (device == nullptr || options.width <= 0 || options.height <= 0 || options.buffers < 2 ||
      options.buffers > kMaxBuffers || options.timeout_ms < 0) {
    return R::failure(CameraError::kBadArgument);
  }
  std::unique_ptr<V4l2Source> source(new (std::nothrow) V4l2Source());
  if (!source) {
    return R::failure(CameraError::kOutOfMemory);
  }
  static_cast<void>(std::snprintf(source->device_, sizeof source->device_, "%s", device));  // long names fail at open()
  source->options_ = options;
  if (options.format == V4l2PixelFormat::kMjpeg) {
    const auto init = source->decoder_.init(options.width, options.height);
    if (!init.ok()) {
      return R::failure(init.error());
    }
  }
  const auto started = source->start();
  if (!started.ok()) {
    return R::failure(started.error());
  }
  return R::success(std::move(source));
}

V4l2Source::~V4l2Source() { stop(); }

// The V4L2 structs are unions by the kernel's design (fmt, parm, m).
// NOLINTBEGIN(cppcoreguidelines-pro-type-union-access)
Status<CameraError> V4l2Source::start() noexcept {
  using S = Status<CameraError>;
  fd_ = ::open(device_, O_RDWR | O_NONBLOCK | O_CLOEXEC);
  if (fd_ < 0) {
    return S::failure(from_errno(errno));
  }
  v4l2_capability cap{};
  if (xioctl(fd_, VIDIOC_QUERYCAP, &cap) < 0) {
    const CameraError e = errno == ENOTTY ? CameraError::kUnsupported : from_errno(errno);
    stop();
    return S::failure(e);
  }
  const std::uint32_t caps = (cap.capabilities & V4L2_CAP_DEVICE_CAPS) != 0U ? cap.device_caps : cap.capabilities;
  if ((caps & V4L2_CAP_VIDEO_CAPTURE) == 0U || (caps & V4L2_CAP_STREAMING) == 0U) {
    stop();
    return S::failure(CameraError::kUnsupported);
  }
  v4l2_format format{};
  format.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  format.fmt.pix.width = static_cast<std::uint32_t>(options_.width);
  format.fmt.pix.height = static_cast<std::uint32_t>(options_.height);
  format.fmt.pix.pixelformat = fourcc(options_.format);
  format.fmt.pix.field = V4L2_FIELD_NONE;
  if (xioctl(fd_, VIDIOC_S_FMT, &format) < 0) {
    const CameraError e = from_errno(errno);
    stop();
    return S::failure(e);
  }
  // The driver may adjust the request: anything but exactly ours is refused.
  if (format.fmt.pix.width != static_cast<std::uint32_t>(options_.width) ||
      format.fmt.pix.height != static_cast<std::uint32_t>(options_.height) ||
      format.fmt.pix.pixelformat != fourcc(options_.format)) {
    stop();
    return S::failure(CameraError::kWrongSize);
  }
  bytes_per_line_ = format.fmt.pix.bytesperline;
  if (options_.rate_hz > 0.0) {
    v4l2_streamparm parm{};
    parm.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    parm.parm.capture.timeperframe.numerator = 1000U;
    parm.parm.capture.timeperframe.denominator = static_cast<std::uint32_t>(std::lround(options_.rate_hz * 1000.0));
    static_cast<void>(xioctl(fd_, VIDIOC_S_PARM, &parm));  // optional: many grabbers have a fixed rate
  }
  v4l2_requestbuffers request{};
  request.count = static_cast<std::uint32_t>(options_.buffers);
  request.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  request.memory = V4L2_MEMORY_MMAP;
  if (xioctl(fd_, VIDIOC_REQBUFS, &request) < 0 || request.count < 2U) {
    const CameraError e = from_errno(errno);
    stop();
    return S::failure(e);
  }
  const auto count = static_cast<int>(request.count < static_cast<std::uint32_t>(kMaxBuffers) ? request.count
                                                                                              : static_cast<std::uint32_t>(kMaxBuffers));
  for (int i = 0; i < count; ++i) {
    v4l2_buffer buffer{};
    buffer.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    buffer.memory = V4L2_MEMORY_MMAP;
    buffer.index = static_cast<std::uint32_t>(i);
    if (xioctl(fd_, VIDIOC_QUERYBUF, &buffer) < 0) {
      const CameraError e = from_errno(errno);
      stop();
      return S::failure(e);
    }
    void* start = ::mmap(nullptr, buffer.length, PROT_READ | PROT_WRITE, MAP_SHARED, fd_, buffer.m.offset);
    if (start == MAP_FAILED) {  // NOLINT(cppcoreguidelines-pro-type-cstyle-cast,performance-no-int-to-ptr): the system's macro
      const CameraError e = from_errno(errno);
      stop();
      return S::failure(e);
    }
    mappings_[static_cast<std::size_t>(i)] = Mapping{start, buffer.length};
    mapped_ = i + 1;
    if (xioctl(fd_, VIDIOC_QBUF, &buffer) < 0) {
      const CameraError e = from_errno(errno);
      stop();
      return S::failure(e);
    }
  }
  int type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  if (xioctl(fd_, VIDIOC_STREAMON, &type) < 0) {
    const CameraError e = from_errno(errno);
    stop();
    return S::failure(e);
  }
  have_driver_sequence_ = false;
  return ok_status<CameraError>();
}

// NOLINTEND(cppcoreguidelines-pro-type-union-access)

void V4l2Source::stop() noexcept {
  if (fd_ >= 0) {
    int type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    static_cast<void>(xioctl(fd_, VIDIOC_STREAMOFF, &type));  // may fail on a lost device: we close anyway
  }
  for (int i = 0; i < mapped_; ++i) {
    Mapping& m = mappings_[static_cast<std::size_t>(i)];
    static_cast<void>(::munmap(m.start, m.length));  // a mapping we made; failure leaves nothing to do
    m = Mapping{};
  }
  mapped_ = 0;
  if (fd_ >= 0) {
    static_cast<void>(::close(fd_));  // nothing to flush on a capture device
    fd_ = -1;
  }
}

Status<CameraError> V4l2Source::reopen() noexcept {
  stop();
  return start();
}

Status<CameraError> V4l2Source::acquire(const MutableImageView& out, FrameInfo& info) noexcept {
  using S = Status<CameraError>;
  if (fd_ < 0) {
    return S::failure(CameraError::kDeviceLost);
  }
  if (!out.valid() || out.width != options_.width || out.height != options_.height) {
    return S::failure(CameraError::kWrongSize);
  }
  pollfd pfd{fd_, POLLIN, 0};
  const int ready = ::poll(&pfd, 1U, options_.timeout_ms);
  if (ready < 0) {
    return S::failure(errno == EINTR ? CameraError::kNotReady : from_errno(errno));
  }
  if (ready == 0) {
    return S::failure(CameraError::kNotReady);
  }
  if ((pfd.revents & (POLLERR | POLLHUP | POLLNVAL)) != 0) {
    return S::failure(CameraError::kDeviceLost);
  }
  // Take the newest filled buffer: older ones are given back at once (a late
  // loop must not work on stale frames).
  v4l2_buffer buffer{};
  bool have = false;
  for (int i = 0; i < kMaxBuffers; ++i) {
    v4l2_buffer next{};
    next.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    next.memory = V4L2_MEMORY_MMAP;
    if (xioctl(fd_, VIDIOC_DQBUF, &next) < 0) {
      if (errno == EAGAIN) {
        break;
      }
      return S::failure(from_errno(errno));
    }
    if (have && xioctl(fd_, VIDIOC_QBUF, &buffer) < 0) {
      return S::failure(from_errno(errno));
    }
    buffer = next;
    have = true;
  }
  if (!have) {
    return S::failure(CameraError::kNotReady);
  }
  if (have_driver_sequence_ && buffer.sequence > last_driver_sequence_ + 1U) {
    dropped_ += buffer.sequence - last_driver_sequence_ - 1U;
  }
  last_driver_sequence_ = buffer.sequence;
  have_driver_sequence_ = true;
  info.sequence = sequence_++;
  if ((buffer.flags & V4L2_BUF_FLAG_TIMESTAMP_MASK) == V4L2_BUF_FLAG_TIMESTAMP_MONOTONIC) {
    info.timestamp_ns = static_cast<std::int64_t>(buffer.timestamp.tv_sec) * 1000000000LL +
                        static_cast<std::int64_t>(buffer.timestamp.tv_usec) * 1000LL;
  } else {
    info.timestamp_ns = monotonic_now_ns();  // unknown time base: the dequeue time, an upper bound
  }
  S status = ok_status<CameraError>();
  const Mapping& m = mappings_[buffer.index < static_cast<std::uint32_t>(kMaxBuffers) ? buffer.index : 0U];
  const auto* data = static_cast<const std::uint8_t*>(m.start);
  const std::size_t used = buffer.bytesused <= m.length ? buffer.bytesused : m.length;
  if ((buffer.flags & V4L2_BUF_FLAG_ERROR) != 0U) {
    status = S::failure(CameraError::kCorrupt);
  } else if (options_.format == V4l2PixelFormat::kMjpeg) {
    status = decoder_.decode(data, used, out);
  } else {
    const std::size_t bpp = options_.format == V4l2PixelFormat::kYuyv ? 2U : 3U;
    const std::size_t stride = bytes_per_line_ != 0U ? bytes_per_line_ : static_cast<std::size_t>(options_.width) * bpp;
    if (used < stride * static_cast<std::size_t>(options_.height)) {
      status = S::failure(CameraError::kTruncated);
    } else if (options_.format == V4l2PixelFormat::kYuyv) {
      yuyv_to_rgb(data, stride, options_.width, options_.height, YuvRange::kLimited, out);
    } else {
      copy_rgb(data, stride, options_.width, options_.height, out);
    }
  }
  if (xioctl(fd_, VIDIOC_QBUF, &buffer) < 0) {
    return S::failure(from_errno(errno));
  }
  return status;
}

}  // namespace hal
}  // namespace tcpest
