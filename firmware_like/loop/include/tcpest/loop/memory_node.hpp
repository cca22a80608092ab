// An in-process stand-in for the CAN node: the NMT state machine reduced to
// what the loop needs, publications kept in a fixed ring (no encoding), and
// knobs to inject NMT commands, SYNCs, encoder priors and bus failures. Used
// by the loop's tests, and by `tcpest run` when the CAN unit is not built.
#pragma once

#include <array>
#include <cstdint>

#include "tcpest/hal/clock/clock.hpp"
#include "tcpest/loop/ports.hpp"

namespace tcpest {
namespace loop {

class MemoryNode final : public NodePort {
 public:
  static constexpr std::size_t kRing = 64U;

  MemoryNode(hal::Clock& clock, bool start_operational, std::int64_t heartbeat_ns, std::int64_t prior_timeout_ns) noexcept;

  Status<PortError> receive(std::int64_t now_ns) noexcept override;
  NodeMode mode() const noexcept override { return mode_; }
  bool take_reset() noexcept override;
  Status<PortError> wait_sync(std::int64_t deadline_ns) noexcept override;
  bool encoder_prior(std::int64_t now_ns, JointPrior& out) noexcept override;
  Status<PortError> publish(const Publication& publication, std::int64_t& latency_ns) noexcept override;
  Status<PortError> housekeeping(std::int64_t now_ns) noexcept override;
  void set_fault(Fault fault, bool active, std::uint32_t detail) noexcept override;
  Status<PortError> recover() noexcept override;
  std::uint64_t frames_dropped() const noexcept override { return dropped_; }

  // Injection (tests).
  void inject_start() noexcept { mode_ = NodeMode::kOperational; }
  void inject_stop() noexcept { mode_ = NodeMode::kStopped; }
  void inject_pre_operational() noexcept { mode_ = NodeMode::kPreOperational; }
  void inject_reset() noexcept;
  void inject_sync() noexcept { ++pending_syncs_; }
  void inject_prior(const JointPrior& prior, std::int64_t received_ns) noexcept;
  void set_bus_up(bool up) noexcept { bus_up_ = up; }
  // A full transmit queue: publish and housekeeping drop their frames (kBusFull).
  void set_tx_full(bool full) noexcept { tx_full_ = full; }

  // Observation.
  std::uint64_t published() const noexcept { return published_; }
  const Publication& publication(std::size_t age) const noexcept;  // 0 = the latest
  std::uint64_t heartbeats() const noexcept { return heartbeats_; }
  std::uint64_t emcy_count() const noexcept { return emcy_; }
  bool fault_active(Fault fault) const noexcept;
  std::uint32_t fault_detail(Fault fault) const noexcept;  // the detail of its last raise (0 before)

 private:
  hal::Clock& clock_;
  bool start_operational_;
  std::int64_t heartbeat_ns_;
  std::int64_t prior_timeout_ns_;
  NodeMode mode_ = NodeMode::kBootUp;
  bool reset_pending_ = false;
  int pending_syncs_ = 0;
  bool have_prior_ = false;
  JointPrior prior_{};
  std::int64_t prior_ns_ = 0;
  bool bus_up_ = true;
  bool tx_full_ = false;
  std::uint64_t dropped_ = 0U;
  std::int64_t next_heartbeat_ns_ = 0;
  std::array<Publication, kRing> ring_{};
  std::uint64_t published_ = 0U;
  std::uint64_t heartbeats_ = 0U;
  std::uint64_t emcy_ = 0U;
  std::uint32_t faults_ = 0U;  // bit per can::Fault (ids below 32)
  std::array<std::uint32_t, 32> fault_details_{};
};

}  // namespace loop
}  // namespace tcpest
