// Optional real-time setup of the loop's thread, each item from the `rt:`
// configuration section: lock all memory (mlockall), SCHED_FIFO priority,
// CPU affinity, pre-faulted stack. Every item that cannot be had (no
// privilege, no such CPU) is reported once, in the returned report, and the
// loop runs without it: none is fatal.
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
  static constexpr std::size_t kMaxMessages = 4U;
  static constexpr std::size_t kMessageLength = 160U;
  char messages[kMaxMessages][kMessageLength] = {};
  std::size_t message_count = 0U;
};

// Applies the settings to the calling thread (and process, for mlockall).
RtReport apply_rt_settings(const RtSettings& settings) noexcept;

}  // namespace loop
}  // namespace tcpest
