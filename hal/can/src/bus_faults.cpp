#include "tcpest/hal/can/bus_faults.hpp"

#include <limits>

namespace tcpest {
namespace hal {
namespace {

std::uint32_t clamp_u32(std::uint64_t value) noexcept {
  constexpr std::uint64_t kMax = std::numeric_limits<std::uint32_t>::max();
  return static_cast<std::uint32_t>(value > kMax ? kMax : value);
}

// Counters only grow, except SO_RXQ_OVFL's, which restarts with a new socket.
std::uint64_t delta(std::uint64_t now, std::uint64_t before) noexcept { return now >= before ? now - before : now; }

}  // namespace

Status<can::CanError> BusFaultMonitor::update(const CanBus& bus, can::Node& node) noexcept {
  const CanBusStats& stats = bus.stats();
  if (!have_reference_) {
    have_reference_ = true;
    restarts_ = stats.restarts;
    kernel_dropped_ = stats.rx_kernel_dropped;
    return ok_status<can::CanError>();
  }
  const std::uint64_t restarts = delta(stats.restarts, restarts_);
  const std::uint64_t kernel_dropped = delta(stats.rx_kernel_dropped, kernel_dropped_);
  restarts_ = stats.restarts;
  kernel_dropped_ = stats.rx_kernel_dropped;

  Status<can::CanError> result = node.report_rx_lost(clamp_u32(kernel_dropped));
  const Status<can::CanError> passive =
      node.set_fault(can::Fault::kCanErrorPassive, bus.state() == BusState::kErrorPassive, 0U);
  const Status<can::CanError> recovered =
      node.set_fault(can::Fault::kCanBusOffRecovered, restarts > 0U, clamp_u32(stats.bus_off));
  if (result.ok() && !passive.ok()) {
    result = passive;
  }
  if (result.ok() && !recovered.ok()) {
    result = recovered;
  }
  return result;
}

}  // namespace hal
}  // namespace tcpest
