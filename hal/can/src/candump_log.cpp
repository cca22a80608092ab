#include "tcpest/hal/can/candump_log.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>

namespace tcpest {
namespace hal {

std::size_t format_candump_line(const can::Frame& frame, std::int64_t timestamp_us, const char* interface_name,
                                char* out, std::size_t capacity) noexcept {
  if (out == nullptr || interface_name == nullptr || interface_name[0] == '\0' ||
      std::strlen(interface_name) >= 16U || frame.id > can::kMaxStandardId || frame.length > can::kMaxDataLength ||
      timestamp_us < 0) {
    return 0U;
  }
  char data[2U * can::kMaxDataLength + 1U] = {};
  constexpr char kHex[] = "0123456789ABCDEF";
  for (std::size_t i = 0U; i < frame.length; ++i) {
    data[2U * i] = kHex[frame.data[i] >> 4U];
    data[2U * i + 1U] = kHex[frame.data[i] & 0x0FU];
  }
  const int written = std::snprintf(out, capacity, "(%lld.%06lld) %s %03X#%s\n",
                                    static_cast<long long>(timestamp_us / 1000000),
                                    static_cast<long long>(timestamp_us % 1000000), interface_name,
                                    static_cast<unsigned>(frame.id), data);
  if (written <= 0 || static_cast<std::size_t>(written) >= capacity) {
    return 0U;
  }
  return static_cast<std::size_t>(written);
}

CandumpLogWriter::~CandumpLogWriter() {
  static_cast<void>(close());  // a destructor cannot report; call close() to see the error
}

Status<CanBusError> CandumpLogWriter::open(const char* path, const char* interface_name) noexcept {
  static_cast<void>(close());  // reopening: the previous file's fate was the caller's to check
  if (path == nullptr || interface_name == nullptr || interface_name[0] == '\0' ||
      std::strlen(interface_name) >= sizeof interface_name_) {
    return Status<CanBusError>::failure(CanBusError::kInvalidArgument);
  }
  const int fd = ::open(path, O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) {
    return Status<CanBusError>::failure(error_from_errno(errno));
  }
  fd_ = fd;
  std::memset(interface_name_, 0, sizeof interface_name_);
  std::memcpy(interface_name_, interface_name, std::strlen(interface_name));
  used_ = 0U;
  lines_ = 0U;
  buffered_lines_ = 0U;
  lines_lost_ = 0U;
  write_errors_ = 0U;
  first_errno_ = 0;
  return ok_status<CanBusError>();
}

void CandumpLogWriter::count_error(int error_number) noexcept {
  if (write_errors_ == 0U) {
    first_errno_ = error_number;
  }
  ++write_errors_;
}

Status<CanBusError> CandumpLogWriter::write(const can::Frame& frame, std::int64_t timestamp_us) noexcept {
  if (fd_ < 0) {
    return Status<CanBusError>::failure(CanBusError::kNotOpen);
  }
  if (buffer_.size() - used_ < kCandumpMaxLine) {
    const Status<CanBusError> flushed = flush();
    if (!flushed) {
      return flushed;
    }
  }
  const std::size_t length =
      format_candump_line(frame, timestamp_us, interface_name_, buffer_.data() + used_, buffer_.size() - used_);
  if (length == 0U) {
    return Status<CanBusError>::failure(CanBusError::kBadFrame);
  }
  used_ += length;
  ++lines_;
  ++buffered_lines_;
  return ok_status<CanBusError>();
}

Status<CanBusError> CandumpLogWriter::flush() noexcept {
  if (fd_ < 0) {
    return Status<CanBusError>::failure(CanBusError::kNotOpen);
  }
  std::size_t done = 0U;
  // Each pass writes at least one byte or fails: bounded by the buffer size.
  while (done < used_) {
    const ssize_t written = ::write(fd_, buffer_.data() + done, used_ - done);
    if (written < 0) {
      if (errno == EINTR) {
        continue;
      }
      const int error_number = errno;
      used_ = 0U;  // those lines are lost: counted, not retried
      lines_lost_ += buffered_lines_;
      buffered_lines_ = 0U;
      count_error(error_number);
      return Status<CanBusError>::failure(error_from_errno(error_number));
    }
    done += static_cast<std::size_t>(written);
  }
  used_ = 0U;
  buffered_lines_ = 0U;
  return ok_status<CanBusError>();
}

Status<CanBusError> CandumpLogWriter::close() noexcept {
  if (fd_ < 0) {
    return ok_status<CanBusError>();
  }
  const Status<CanBusError> flushed = flush();
  const int result = ::close(fd_);
  const int error_number = errno;
  fd_ = -1;
  if (result < 0) {
    count_error(error_number);  // also after a failed flush: both are lost data
  }
  if (!flushed) {
    return flushed;
  }
  if (result < 0) {
    return Status<CanBusError>::failure(error_from_errno(error_number));
  }
  return ok_status<CanBusError>();
}

}  // namespace hal
}  // namespace tcpest
