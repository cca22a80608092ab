#include "tcpest/hal/camera/sim_camera.hpp"

namespace tcpest {
namespace hal {

Status<CameraError> SimCamera::acquire(const MutableImageView& out, FrameInfo& info) noexcept {
  if (!out.valid()) {
    return Status<CameraError>::failure(CameraError::kBadArgument);
  }
  if (out.width != renderer_.width() || out.height != renderer_.height()) {
    return Status<CameraError>::failure(CameraError::kWrongSize);
  }
  const std::uint32_t count = renderer_.frame_count();
  if (count != 0U && next_ >= count) {
    if (!loop_) {
      return Status<CameraError>::failure(CameraError::kEndOfStream);
    }
    next_ = 0U;
  }
  info.timestamp_ns = monotonic_now_ns();
  info.sequence = sequence_++;
  truth_ = FrameTruth{};
  const std::uint32_t index = next_++;
  const auto drawn = renderer_.render(index, out, truth_);
  if (!drawn.ok()) {
    truth_ = FrameTruth{};
  }
  return drawn;
}

Status<CameraError> SimCamera::reopen() noexcept {
  next_ = 0U;
  return ok_status<CameraError>();
}

}  // namespace hal
}  // namespace tcpest
