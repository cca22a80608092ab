// Optional real-time setup of the loop's thread, each item from the `rt:`
// configuration section: lock all memory (mlockall), SCHED_FIFO priority,
// CPU affinity, pre-faulted stack, CPU wake-up latency request. Every item
// that cannot be had (no privilege, no such CPU, no such device) is reported
// once, in the returned report, and the loop runs without it: none is fatal.
// A stack pre-fault larger than the calling thread's stack can take would
// crash the process: the configuration refuses it (config.cpp, with
// max_prefault_stack_kb()), and apply_rt_settings() skips it (reported).
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
  static constexpr std::size_t kMaxMessages = 5U;  // one per item that can fail
  static constexpr std::size_t kMessageLength = 160U;
  char messages[kMaxMessages][kMessageLength] = {};
  std::size_t message_count = 0U;
};

// rt.prefault_stack_kb's upper bound, whatever the stack.
constexpr long long kMaxPrefaultStackKb = 65536;
// The stack left unused below a pre-fault: signal frames and the calls made
// while the pre-faulted block is live.
constexpr long long kPrefaultStackMarginKb = 64;

// The largest rt.prefault_stack_kb the calling thread can pre-fault safely:
// the stack still free below the caller (its size from the thread's
// attributes, for the main thread RLIMIT_STACK) less kPrefaultStackMarginKb,
// at most kMaxPrefaultStackKb; 0 when nothing can be. Start-up only.
long long max_prefault_stack_kb() noexcept;

// Applies the settings to the calling thread (and process, for mlockall and
// the CPU latency request). A stack pre-fault beyond max_prefault_stack_kb()
// is not done (reported).
RtReport apply_rt_settings(const RtSettings& settings) noexcept;

}  // namespace loop
}  // namespace tcpest
