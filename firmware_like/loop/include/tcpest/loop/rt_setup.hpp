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

// A CPU wake-up latency request: the open /dev/cpu_dma_latency. The kernel
// holds the request while the file is open and drops it when it is closed
// or the process ends (also on a crash). One owner: move-only, so that the
// request is withdrawn once, by release() or by the destructor.
class CpuLatencyRequest {
 public:
  CpuLatencyRequest() noexcept = default;
  explicit CpuLatencyRequest(int fd) noexcept : fd_(fd) {}
  CpuLatencyRequest(const CpuLatencyRequest&) = delete;
  CpuLatencyRequest& operator=(const CpuLatencyRequest&) = delete;
  CpuLatencyRequest(CpuLatencyRequest&& other) noexcept : fd_(other.fd_) { other.fd_ = -1; }
  CpuLatencyRequest& operator=(CpuLatencyRequest&& other) noexcept;
  ~CpuLatencyRequest() { release(); }

  bool held() const noexcept { return fd_ >= 0; }
  // Withdraws the request, if one is held; a second call does nothing.
  void release() noexcept;

 private:
  int fd_ = -1;
};

// What apply_rt_settings() obtained. Move-only (it owns the latency request).
struct RtReport {
  bool memory_locked = false;
  bool fifo = false;
  bool pinned = false;
  bool stack_prefaulted = false;
  CpuLatencyRequest cpu_latency;  // held while the report lives, or until released
  static constexpr std::size_t kMaxMessages = 4U;  // one per item that can fail
  static constexpr std::size_t kMessageLength = 160U;
  char messages[kMaxMessages][kMessageLength] = {};
  std::size_t message_count = 0U;
};

// Applies the settings to the calling thread (and process, for mlockall and
// the CPU latency request).
RtReport apply_rt_settings(const RtSettings& settings) noexcept;

}  // namespace loop
}  // namespace tcpest
