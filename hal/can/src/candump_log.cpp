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

namespace {

int hex_digit(char c) noexcept {
  if (c >= '0' && c <= '9') {
    return c - '0';
  }
  if (c >= 'A' && c <= 'F') {
    return c - 'A' + 10;
  }
  if (c >= 'a' && c <= 'f') {
    return c - 'a' + 10;
  }
  return -1;
}

// Decimal digits at `p` (at most max_digits, at least one) into `value`.
const char* read_decimal(const char* p, int max_digits, std::int64_t& value) noexcept {
  value = 0;
  int digits = 0;
  while (digits < max_digits && *p >= '0' && *p <= '9') {
    value = value * 10 + (*p - '0');
    ++p;
    ++digits;
  }
  return digits > 0 ? p : nullptr;
}

}  // namespace

bool parse_candump_line(const char* line, can::Frame& frame, std::int64_t& timestamp_us) noexcept {
  if (line == nullptr || line[0] != '(') {
    return false;
  }
  std::int64_t seconds = 0;
  std::int64_t micros = 0;
  const char* p = read_decimal(line + 1, 12, seconds);
  if (p == nullptr || *p != '.') {
    return false;
  }
  const char* fraction = p + 1;
  p = read_decimal(fraction, 6, micros);
  if (p == nullptr || p - fraction != 6 || *p != ')' || p[1] != ' ') {
    return false;
  }
  p += 2;
  int name_length = 0;
  while (*p != ' ' && *p != '\0' && name_length < 16) {
    ++p;
    ++name_length;
  }
  if (name_length == 0 || name_length >= 16 || *p != ' ') {
    return false;
  }
  ++p;
  std::uint32_t id = 0U;
  for (int i = 0; i < 3; ++i) {
    const int d = hex_digit(p[i]);
    if (d < 0) {
      return false;
    }
    id = (id << 4U) | static_cast<std::uint32_t>(d);
  }
  p += 3;
  if (*p != '#' || id > can::kMaxStandardId) {
    return false;
  }
  ++p;
  can::Frame parsed;
  parsed.id = id;
  std::uint8_t length = 0U;
  while (*p != '\0' && *p != '\n' && *p != '\r') {
    const int high = hex_digit(p[0]);
    const int low = high < 0 ? -1 : hex_digit(p[1]);
    if (low < 0 || length >= can::kMaxDataLength) {
      return false;
    }
    parsed.data[length] = static_cast<std::uint8_t>((high << 4) | low);
    ++length;
    p += 2;
  }
  parsed.length = length;
  frame = parsed;
  timestamp_us = seconds * 1000000 + micros;
  return true;
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
