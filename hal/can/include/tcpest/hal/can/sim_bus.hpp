// A simulated CAN bus in the process: a few endpoints (each a CanBus) on one
// wire, deterministic (simulated time, no threads, no randomness), with fault
// injection: drop, corrupt, delay, bus-off, and bounded receive queues that
// overflow like the kernel's. Used by tests and the demo.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>

#include "tcpest/common/static_vector.hpp"
#include "tcpest/hal/can/bus.hpp"

namespace tcpest {
namespace hal {

class SimBus;

struct SimFaults {
  std::uint32_t drop_next = 0U;       // drop this many upcoming frames
  std::uint32_t drop_every = 0U;      // then drop every n-th frame (0: none)
  std::uint32_t corrupt_next = 0U;    // XOR corrupt_mask into data[corrupt_byte] of this many
  std::uint8_t corrupt_byte = 0U;
  std::uint8_t corrupt_mask = 0x01U;
  std::int64_t delay_us = 0;          // delivery delay (constant: order is kept)
  bool bus_off = false;               // sends fail with kBusOff, states read kBusOff (use SimBus::set_bus_off)
};

struct SimFaultCounters {
  std::uint64_t dropped = 0U;
  std::uint64_t corrupted = 0U;
};

class SimEndpoint final : public CanBus {
 public:
  static constexpr std::size_t kQueueCapacity = 256U;
  static constexpr std::size_t kMaxRxIds = 16U;

  SimEndpoint() noexcept = default;
  ~SimEndpoint() override = default;
  SimEndpoint(const SimEndpoint&) = delete;
  SimEndpoint& operator=(const SimEndpoint&) = delete;
  SimEndpoint(SimEndpoint&&) = delete;
  SimEndpoint& operator=(SimEndpoint&&) = delete;

  // Receive only these standard IDs (empty: all), like a kernel filter.
  Status<CanBusError> set_rx_ids(const std::uint32_t* ids, std::size_t count) noexcept;

  Status<CanBusError> send(const can::Frame& frame) noexcept override;
  Result<std::size_t, CanBusError> receive(ReceivedFrame* out, std::size_t max_frames) noexcept override;
  BusState state() const noexcept override;
  const CanBusStats& stats() const noexcept override { return stats_; }

 private:
  friend class SimBus;
  struct Pending {
    ReceivedFrame received;
    std::int64_t due_us = 0;
  };
  bool accepts(std::uint32_t id) const noexcept;
  void deliver(const can::Frame& frame, std::int64_t sent_us, std::int64_t due_us) noexcept;

  SimBus* bus_ = nullptr;
  StaticVector<std::uint32_t, kMaxRxIds> rx_ids_{};
  std::array<Pending, kQueueCapacity> queue_{};
  std::size_t head_ = 0U;
  std::size_t size_ = 0U;
  CanBusStats stats_{};
};

class SimBus {
 public:
  static constexpr std::size_t kMaxEndpoints = 4U;

  SimBus() noexcept;
  SimBus(const SimBus&) = delete;
  SimBus& operator=(const SimBus&) = delete;
  SimBus(SimBus&&) = delete;
  SimBus& operator=(SimBus&&) = delete;

  // Endpoint i (0..kMaxEndpoints-1): a frame sent by one is received by all others.
  SimEndpoint& endpoint(std::size_t index) noexcept;

  // Simulated time: frames are stamped with it and delivered when due.
  void set_time_us(std::int64_t now_us) noexcept { now_us_ = now_us; }
  std::int64_t time_us() const noexcept { return now_us_; }

  SimFaults& faults() noexcept { return faults_; }
  // Bus-off and recovery as a controller reports them: counted in every
  // endpoint's bus_off / restarts.
  void set_bus_off(bool bus_off) noexcept;
  const SimFaultCounters& fault_counters() const noexcept { return fault_counters_; }

 private:
  friend class SimEndpoint;
  void transmit(const SimEndpoint& sender, const can::Frame& frame) noexcept;

  std::array<SimEndpoint, kMaxEndpoints> endpoints_{};
  SimFaults faults_{};
  SimFaultCounters fault_counters_{};
  std::uint64_t frames_on_wire_ = 0U;
  std::int64_t now_us_ = 0;
};

}  // namespace hal
}  // namespace tcpest
