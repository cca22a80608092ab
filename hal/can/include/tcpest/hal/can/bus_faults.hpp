// Turns a bus's health into the node's CAN faults (docs/can-protocol.md,
// EMCY faults 9-11), so that the loop needs one call per cycle:
//   node.receive(...); monitor.update(bus, node); ... node.collect(...)
// Fault 12 (frames dropped on send) is the sender's: the loop raises it for
// the cycles whose sends dropped frames and while the bus is lost
// (loop::Executive), so that one owner decides it.
#pragma once

#include <cstdint>

#include "tcpest/can_iface/error.hpp"
#include "tcpest/can_iface/node.hpp"
#include "tcpest/common/result.hpp"
#include "tcpest/hal/can/bus.hpp"

namespace tcpest {
namespace hal {

class BusFaultMonitor {
 public:
  // Compares the bus's counters with the previous call:
  //   frames the kernel dropped      -> node.report_rx_lost (fault 9)
  //   state kErrorPassive            -> fault 10 while it lasts
  //   a restart after bus-off        -> fault 11 for one cycle (detail: bus-off count)
  // The first call only takes the counters as its reference.
  Status<can::CanError> update(const CanBus& bus, can::Node& node) noexcept;

 private:
  bool have_reference_ = false;
  std::uint64_t restarts_ = 0U;
  std::uint64_t kernel_dropped_ = 0U;
};

}  // namespace hal
}  // namespace tcpest
