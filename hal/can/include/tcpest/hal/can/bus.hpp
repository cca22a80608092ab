// The CAN bus as the loop sees it: send one classic frame, read a bounded
// batch of received frames with their receive timestamps, and the bus's
// health. Backends: SocketCAN (socketcan_bus.hpp) and an in-process
// simulation with fault injection (sim_bus.hpp).
#pragma once

#include <cstddef>
#include <cstdint>

#include "tcpest/can_iface/frame.hpp"
#include "tcpest/common/result.hpp"

namespace tcpest {
namespace hal {

// Every errno of the bus is mapped once, to one of these.
enum class CanBusError : std::uint8_t {
  kNotSupported,      // no CAN in this kernel (EAFNOSUPPORT, EPROTONOSUPPORT)
  kNoSuchInterface,   // the named interface does not exist (ENODEV, ENXIO)
  kInterfaceDown,     // the interface is down (ENETDOWN); reopening is pending
  kTxQueueFull,       // ENOBUFS / EAGAIN after the bounded retries: frame dropped
  kBusOff,            // the controller is bus-off
  kPermissionDenied,  // EPERM, EACCES
  kBadFrame,          // not a classic frame (id > 0x7FF or length > 8)
  kInvalidArgument,   // bad name or configuration (EINVAL, ENAMETOOLONG)
  kNotOpen,           // used before open()
  kOutOfResources,    // EMFILE, ENFILE, ENOMEM
  kIoError,           // any other errno (kept in CanBusStats::last_errno)
};
const char* to_string(CanBusError error) noexcept;
// The one place where errno values become CanBusError.
CanBusError error_from_errno(int error_number) noexcept;

enum class BusState : std::uint8_t {
  kUp,            // sending and receiving
  kErrorPassive,  // the controller reported warning / error passive
  kBusOff,        // the controller reported bus-off (until restarted)
  kDown,          // interface down or gone; the backend reopens when it is back
};
const char* to_string(BusState state) noexcept;

struct ReceivedFrame {
  can::Frame frame;
  // Receive time in microseconds: the kernel's SO_TIMESTAMP (CLOCK_REALTIME)
  // for SocketCAN, the simulated time for the simulated bus.
  std::int64_t timestamp_us = 0;
};

struct CanBusStats {
  std::uint64_t tx_frames = 0U;         // frames handed to the driver
  std::uint64_t tx_retries = 0U;        // retries after a full TX queue
  std::uint64_t tx_dropped = 0U;        // frames given up (queue full, down, bus-off)
  std::uint64_t rx_frames = 0U;         // data frames returned to the caller
  std::uint64_t rx_kernel_dropped = 0U;  // frames the kernel dropped (socket queue full)
  std::uint64_t rx_ignored = 0U;        // extended / remote / malformed frames skipped
  std::uint64_t error_frames = 0U;      // error frames seen (any class)
  std::uint64_t bus_off = 0U;
  std::uint64_t controller_problems = 0U;
  std::uint64_t restarts = 0U;
  std::uint64_t down_events = 0U;       // times the interface was found down or gone
  std::uint64_t recoveries = 0U;        // back up after a down event (reopened if it had gone)
  int last_errno = 0;                   // the last errno seen, for diagnostics
};

class CanBus {
 public:
  CanBus() noexcept = default;
  virtual ~CanBus() = default;
  CanBus(const CanBus&) = delete;
  CanBus& operator=(const CanBus&) = delete;
  CanBus(CanBus&&) = delete;
  CanBus& operator=(CanBus&&) = delete;

  // Sends one frame, or says why it could not (the frame is then dropped
  // and counted; nothing is queued behind the caller's back).
  virtual Status<CanBusError> send(const can::Frame& frame) noexcept = 0;
  // Reads what has arrived, at most max_frames, never waiting. Returns the
  // number of frames written to out.
  virtual Result<std::size_t, CanBusError> receive(ReceivedFrame* out, std::size_t max_frames) noexcept = 0;
  virtual BusState state() const noexcept = 0;
  virtual const CanBusStats& stats() const noexcept = 0;
};

}  // namespace hal
}  // namespace tcpest
