// SocketCAN backend: a raw CAN socket bound to one named interface,
// non-blocking, with kernel receive filters for the consumed IDs, error
// frames (bus-off, controller problems, restarted) decoded into the bus
// state, SO_TIMESTAMP receive times, SO_RXQ_OVFL kernel drop counts, a
// bounded retry when the TX queue is full, and reopening after the
// interface went down or disappeared.
#pragma once

#include <net/if.h>

#include <cstdint>

#include "tcpest/common/static_vector.hpp"
#include "tcpest/hal/can/bus.hpp"

namespace tcpest {
namespace hal {

constexpr std::size_t kMaxRxFilters = 16U;

struct SocketCanConfig {
  // Standard IDs to receive (exact match); empty: every standard data frame.
  StaticVector<std::uint32_t, kMaxRxFilters> rx_ids{};
  // ENOBUFS/EAGAIN: this many retries, tx_retry_wait_us apart, then a drop.
  std::uint32_t tx_retry_count = 3U;
  std::int64_t tx_retry_wait_us = 100;
  // While down, look for the interface at most this often.
  std::int64_t reopen_interval_us = 100000;
  // SO_RCVBUF in bytes; 0 keeps the kernel default.
  int receive_buffer_bytes = 0;
};

class SocketCanBus final : public CanBus {
 public:
  SocketCanBus() noexcept = default;
  ~SocketCanBus() override;
  SocketCanBus(const SocketCanBus&) = delete;
  SocketCanBus& operator=(const SocketCanBus&) = delete;
  SocketCanBus(SocketCanBus&&) = delete;
  SocketCanBus& operator=(SocketCanBus&&) = delete;

  // Opens and binds. kNotSupported without kernel CAN, kNoSuchInterface,
  // kInterfaceDown (the object stays usable and reopens when it comes up).
  Status<CanBusError> open(const char* interface_name, const SocketCanConfig& config) noexcept;
  void close() noexcept;

  Status<CanBusError> send(const can::Frame& frame) noexcept override;
  Result<std::size_t, CanBusError> receive(ReceivedFrame* out, std::size_t max_frames) noexcept override;
  BusState state() const noexcept override { return state_; }
  const CanBusStats& stats() const noexcept override { return stats_; }

  // The socket, for poll() by a caller that wants to wait (-1 while down).
  int fd() const noexcept { return fd_; }

 private:
  Status<CanBusError> open_socket() noexcept;
  void mark_down(int error_number) noexcept;
  bool interface_up() const noexcept;
  // While down: back to up if the interface is (rate limited), reopening
  // the socket if the interface had gone. True when usable.
  bool ensure_open() noexcept;
  void handle_error_frame(std::uint32_t can_id, const std::uint8_t* data) noexcept;

  char name_[IFNAMSIZ] = {};
  SocketCanConfig config_{};
  bool configured_ = false;
  int fd_ = -1;
  BusState state_ = BusState::kDown;
  std::int64_t next_reopen_us_ = 0;
  CanBusStats stats_{};
};

}  // namespace hal
}  // namespace tcpest
