// A writer of candump's log format, one frame a line:
//   (1700000000.123456) vcan0 190#0102030405060708
// so that any run can be replayed with `canplayer -I file` and read with the
// usual can-utils. Buffered in a fixed 4 KB block, written with write(2).
// A failed write(2) or close(2) (a full disk) is returned to the caller that
// caused it, and counted: callers that log on the side and go on (the CAN
// node) leave the count to whoever reports the run.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>

#include "tcpest/can_iface/frame.hpp"
#include "tcpest/hal/can/bus.hpp"

namespace tcpest {
namespace hal {

// Longest line: "(" 20 digits "." 6 ") " 15-char name " " 3 "#" 16 "\n" < 80.
constexpr std::size_t kCandumpMaxLine = 80U;

// Formats one line into `out` (with its '\n', NUL-terminated). Returns the
// length without the NUL, or 0 if the frame or name is invalid.
std::size_t format_candump_line(const can::Frame& frame, std::int64_t timestamp_us, const char* interface_name,
                                char* out, std::size_t capacity) noexcept;

// Reads one line of that format back (a trailing '\n' is allowed):
// "(SECONDS.MICROSECONDS) IFACE ID#DATA" with a 3-digit standard ID and 0..8
// data bytes in hex. False for anything else (extended IDs, remote or CAN FD
// frames, a damaged line); nothing is written then.
bool parse_candump_line(const char* line, can::Frame& frame, std::int64_t& timestamp_us) noexcept;

class CandumpLogWriter {
 public:
  CandumpLogWriter() noexcept = default;
  ~CandumpLogWriter();
  CandumpLogWriter(const CandumpLogWriter&) = delete;
  CandumpLogWriter& operator=(const CandumpLogWriter&) = delete;
  CandumpLogWriter(CandumpLogWriter&&) = delete;
  CandumpLogWriter& operator=(CandumpLogWriter&&) = delete;

  // Creates (truncates) the file; interface_name is written on every line.
  Status<CanBusError> open(const char* path, const char* interface_name) noexcept;
  // timestamp_us: microseconds since the epoch (candump uses CLOCK_REALTIME).
  Status<CanBusError> write(const can::Frame& frame, std::int64_t timestamp_us) noexcept;
  Status<CanBusError> flush() noexcept;
  // Flushes and closes; safe to call twice.
  Status<CanBusError> close() noexcept;
  // Lines accepted (buffered) since open(); not all reached the file when write_errors() > 0.
  std::uint64_t lines_written() const noexcept { return lines_; }
  // Failed write(2) and close(2) calls since open(), and the errno of the
  // first (0: none). A failed write loses the lines buffered then (all of
  // them counted in lines_lost(), also those a short write had written).
  std::uint64_t write_errors() const noexcept { return write_errors_; }
  int first_errno() const noexcept { return first_errno_; }
  std::uint64_t lines_lost() const noexcept { return lines_lost_; }

 private:
  int fd_ = -1;
  char interface_name_[16] = {};
  std::array<char, 4096> buffer_{};
  std::size_t used_ = 0U;
  std::uint64_t lines_ = 0U;
  std::uint64_t buffered_lines_ = 0U;  // lines in buffer_
  std::uint64_t lines_lost_ = 0U;
  std::uint64_t write_errors_ = 0U;
  int first_errno_ = 0;

  void count_error(int error_number) noexcept;
};

}  // namespace hal
}  // namespace tcpest
