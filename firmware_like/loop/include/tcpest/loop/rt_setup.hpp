// Optional real-time setup of the loop's thread, each item from the `rt:`
// configuration section: lock all memory (mlockall), SCHED_FIFO priority,
// CPU affinity, pre-faulted stack, CPU wake-up latency request. Every item
// that cannot be had (no privilege, no such CPU, no such device) is reported
// once, in the returned report, and the loop runs without it: none is fatal.
#pragma once

#include <cstddef>

#include "tcpest/loop/config.hpp"

namespace tcpest {
namespace loop {

struct RtReport {
  bool memory_locked = false;
  bool fifo = false;
  bool pinned = false;
  bool stack_prefaulted = false;
  // The open /dev/cpu_dma_latency: the kernel holds the request while it is
  // open, and drops it when the process ends (also on a crash). -1 = none.
  int cpu_latency_fd = -1;
  static constexpr std::size_t kMaxMessages = 4U;  // one per item that can fail
  static constexpr std::size_t kMessageLength = 160U;
  char messages[kMaxMessages][kMessageLength] = {};
  std::size_t message_count = 0U;
};

// Applies the settings to the calling thread (and process, for mlockall and
// the CPU latency request).
RtReport apply_rt_settings(const RtSettings& settings) noexcept;

// Withdraws the CPU latency request, if one is held (the other items stay).
// Optional: a request held until the process exits is withdrawn then.
void release_cpu_latency(RtReport& report) noexcept;

}  // namespace loop
}  // namespace tcpest
