// The loop's NodePort over the real thing: can_iface's Node (NMT, E2E,
// heartbeat, EMCY, PDO encoding) on a hal/can bus (SocketCAN or the simulated
// bus), with every frame sent or received also written to a candump-format
// log when one is given. Per cycle (can_iface/README.md): receive the bus
// into Node::receive, Node::publish the estimate, Node::collect and send;
// at housekeeping the bus's health into faults 9-11 (BusFaultMonitor).
#pragma once

#include <array>
#include <cstdint>

#include "tcpest/can_iface/node.hpp"
#include "tcpest/hal/can/bus.hpp"
#include "tcpest/hal/can/bus_faults.hpp"
#include "tcpest/hal/can/candump_log.hpp"
#include "tcpest/hal/can/sim_bus.hpp"
#include "tcpest/hal/can/socketcan_bus.hpp"
#include "tcpest/hal/clock/clock.hpp"
#include "tcpest/loop/config.hpp"
#include "tcpest/loop/ports.hpp"

namespace tcpest {
namespace loop {

// The NodeConfig the loop's settings ask for.
can::NodeConfig node_config(const LoopConfig& config) noexcept;

// Sees every frame the port sends or receives, stamped as the candump log
// stamps it (microseconds of wall-clock time): a recorder that writes the
// log off the cycle. Called inside the cycle: it must neither block nor
// allocate.
class FrameTap {
 public:
  FrameTap() noexcept = default;
  virtual ~FrameTap() = default;
  FrameTap(const FrameTap&) = delete;
  FrameTap& operator=(const FrameTap&) = delete;
  FrameTap(FrameTap&&) = delete;
  FrameTap& operator=(FrameTap&&) = delete;
  virtual void on_frame(const can::Frame& frame, std::int64_t wall_us) noexcept = 0;
};

class CanNodePort final : public NodePort {
 public:
  // `sim` (optional): the simulated bus whose time follows the loop's clock.
  // `log` (optional): every frame sent and received, stamped with wall-clock
  // time derived from the loop's clock; `log_interface` names it in the log.
  CanNodePort(hal::Clock& clock, hal::CanBus& bus, hal::SimBus* sim, hal::CandumpLogWriter* log,
              const char* log_interface) noexcept;

  Status<can::CanError> configure(const can::NodeConfig& config) noexcept;
  // With SocketCAN, wait_sync() sleeps in poll() on its socket.
  void set_socket(const hal::SocketCanBus* socket) noexcept { socket_ = socket; }
  // Every frame sent or received also goes to `tap` (nullptr: none).
  void set_tap(FrameTap* tap) noexcept { tap_ = tap; }
  // The interface name the candump lines carry.
  const char* log_interface() const noexcept { return log_interface_; }

  Status<PortError> receive(std::int64_t now_ns) noexcept override;
  NodeMode mode() const noexcept override;
  bool take_reset() noexcept override;
  Status<PortError> wait_sync(std::int64_t deadline_ns) noexcept override;
  bool encoder_prior(std::int64_t now_ns, JointPrior& out) noexcept override;
  Status<PortError> publish(const Publication& publication, std::int64_t& latency_ns) noexcept override;
  Status<PortError> housekeeping(std::int64_t now_ns) noexcept override;
  void set_fault(Fault fault, bool active, std::uint32_t detail) noexcept override;
  Status<PortError> recover() noexcept override;
  std::uint64_t frames_dropped() const noexcept override { return send_errors_; }

  const can::Node& node() const noexcept { return node_; }
  std::uint64_t frames_sent() const noexcept { return frames_sent_; }
  std::uint64_t send_errors() const noexcept { return send_errors_; }

 private:
  Status<PortError> flush(std::int64_t now_ns) noexcept;
  void log(const can::Frame& frame, std::int64_t now_ns) noexcept;
  void set_bus_time(std::int64_t now_ns) noexcept;

  hal::Clock& clock_;
  hal::CanBus& bus_;
  hal::SimBus* sim_;
  const hal::SocketCanBus* socket_ = nullptr;
  hal::CandumpLogWriter* log_;
  FrameTap* tap_ = nullptr;
  char log_interface_[16] = {};
  std::int64_t wall_offset_ns_ = 0;  // CLOCK_REALTIME - loop clock, fixed at construction
  can::Node node_{};
  hal::BusFaultMonitor monitor_{};
  can::TxBatch batch_{};
  std::array<hal::ReceivedFrame, can::kMaxRxPerCycle> rx_{};
  std::array<can::Frame, can::kMaxRxPerCycle> rx_frames_{};
  std::uint32_t syncs_ = 0U;
  bool reset_ = false;
  std::uint64_t frames_sent_ = 0U;
  std::uint64_t send_errors_ = 0U;
};

}  // namespace loop
}  // namespace tcpest
