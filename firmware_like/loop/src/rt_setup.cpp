#include "tcpest/loop/rt_setup.hpp"

#include <alloca.h>
#include <fcntl.h>
#include <pthread.h>
#include <sched.h>
#include <sys/mman.h>
#include <sys/resource.h>
#include <unistd.h>

#include <cerrno>
#include <cstdint>
#include <cstdio>
#include <cstring>

namespace tcpest {
namespace loop {

namespace {

void note(RtReport& report, const char* what, int error) noexcept {
  if (report.message_count >= RtReport::kMaxMessages) {
    return;
  }
  char reason[96] = {};
  // strerror_r (GNU) returns the message, possibly not in `reason`.
  const char* text = strerror_r(error, reason, sizeof reason);
  static_cast<void>(std::snprintf(report.messages[report.message_count], RtReport::kMessageLength,
                                  "%s: %s (continuing without it)", what, text));  // truncation is harmless
  ++report.message_count;
}

// A stack pre-fault beyond what the thread's stack can take: not done.
void note_prefault_refused(RtReport& report, int requested_kb, long long max_kb) noexcept {
  if (report.message_count >= RtReport::kMaxMessages) {
    return;
  }
  static_cast<void>(std::snprintf(report.messages[report.message_count], RtReport::kMessageLength,
                                  "rt.prefault_stack_kb: %d is more than this thread's stack can take (allowed 0..%lld)"
                                  " (continuing without it)",
                                  requested_kb, max_kb));  // truncation is harmless
  ++report.message_count;
}

// The lowest usable address of the calling thread's stack (above its guard
// page; for the main thread its top less RLIMIT_STACK), 0 if unknown.
std::uintptr_t stack_low_end() noexcept {
  pthread_attr_t attributes{};
  if (::pthread_getattr_np(::pthread_self(), &attributes) != 0) {
    return 0U;
  }
  void* address = nullptr;
  std::size_t size = 0U;
  const int got = ::pthread_attr_getstack(&attributes, &address, &size);
  static_cast<void>(::pthread_attr_destroy(&attributes));  // cannot fail for an initialised attribute object
  return got == 0 ? reinterpret_cast<std::uintptr_t>(address) : 0U;  // NOLINT(cppcoreguidelines-pro-type-reinterpret-cast): an address compared, never dereferenced
}

// Touches `bytes` of stack below the caller so that the pages are mapped
// (and locked, after mlockall) before the first cycle needs them. The caller
// checks `bytes` against max_prefault_stack_kb().
__attribute__((noinline)) void prefault_stack(std::size_t bytes) noexcept {
  // cppcheck-suppress allocaCalled ; the only way to touch N KiB of our own stack without recursion; start-up only, N bounded by the thread's free stack less a margin (max_prefault_stack_kb)
  auto* block = static_cast<volatile unsigned char*>(alloca(bytes));
  for (std::size_t i = 0; i < bytes; i += 4096U) {
    block[i] = 0U;
  }
}

// Asks the kernel to keep every CPU's wake-up latency at or below
// `latency_us` (PM QoS): the request is the 32-bit value written to the open
// device, and holds while the file stays open. Returns the descriptor, or -1
// with the failure noted.
int open_cpu_latency_request(RtReport& report, int latency_us) noexcept {
  const int fd = ::open("/dev/cpu_dma_latency", O_WRONLY | O_CLOEXEC);
  if (fd < 0) {
    note(report, "rt.cpu_latency_us: open /dev/cpu_dma_latency", errno);
    return -1;
  }
  const std::int32_t value = latency_us;
  const ssize_t written = ::write(fd, &value, sizeof value);
  if (written != static_cast<ssize_t>(sizeof value)) {
    note(report, "rt.cpu_latency_us: write /dev/cpu_dma_latency", written < 0 ? errno : EIO);
    static_cast<void>(::close(fd));  // nothing was requested; a close error changes nothing
    return -1;
  }
  return fd;
}

}  // namespace

long long max_prefault_stack_kb() noexcept {
  // Where the caller's frames end: the pre-fault starts a few bytes below.
  const auto here = reinterpret_cast<std::uintptr_t>(__builtin_frame_address(0));  // NOLINT(cppcoreguidelines-pro-type-reinterpret-cast): an address compared, never dereferenced
  const std::uintptr_t low = stack_low_end();
  unsigned long long free_bytes = 0U;
  if (low != 0U && low < here) {
    free_bytes = here - low;
  } else {
    // The thread's stack is unknown: RLIMIT_STACK, of which the callers may use half.
    rlimit limit{};
    if (::getrlimit(RLIMIT_STACK, &limit) != 0) {
      return 0;
    }
    free_bytes = limit.rlim_cur == RLIM_INFINITY ? static_cast<unsigned long long>(kMaxPrefaultStackKb) * 2048U
                                                 : static_cast<unsigned long long>(limit.rlim_cur) / 2U;
  }
  const auto free_kb = static_cast<long long>(free_bytes / 1024U);
  if (free_kb <= kPrefaultStackMarginKb) {
    return 0;
  }
  return free_kb - kPrefaultStackMarginKb < kMaxPrefaultStackKb ? free_kb - kPrefaultStackMarginKb
                                                                : kMaxPrefaultStackKb;
}

RtReport apply_rt_settings(const RtSettings& settings) noexcept {
  RtReport report;
  if (settings.lock_memory) {
    if (::mlockall(MCL_CURRENT | MCL_FUTURE) == 0) {
      report.memory_locked = true;
    } else {
      note(report, "rt.lock_memory: mlockall", errno);
    }
  }
  if (settings.cpu >= 0) {
    cpu_set_t set;
    CPU_ZERO(&set);
    CPU_SET(static_cast<std::size_t>(settings.cpu), &set);
    const int rc = ::pthread_setaffinity_np(::pthread_self(), sizeof set, &set);
    if (rc == 0) {
      report.pinned = true;
    } else {
      note(report, "rt.cpu: pthread_setaffinity_np", rc);
    }
  }
  if (settings.fifo_priority > 0) {
    sched_param param{};
    param.sched_priority = settings.fifo_priority;
    const int rc = ::pthread_setschedparam(::pthread_self(), SCHED_FIFO, &param);
    if (rc == 0) {
      report.fifo = true;
    } else {
      note(report, "rt.fifo_priority: pthread_setschedparam(SCHED_FIFO)", rc);
    }
  }
  if (settings.prefault_stack_kb > 0) {
    const long long max_kb = max_prefault_stack_kb();
    if (settings.prefault_stack_kb <= max_kb) {
      prefault_stack(static_cast<std::size_t>(settings.prefault_stack_kb) * 1024U);
      report.stack_prefaulted = true;
    } else {
      note_prefault_refused(report, settings.prefault_stack_kb, max_kb);
    }
  }
  if (settings.cpu_latency_us >= 0) {
    report.cpu_latency = CpuLatencyRequest(open_cpu_latency_request(report, settings.cpu_latency_us));
  }
  return report;
}

CpuLatencyRequest& CpuLatencyRequest::operator=(CpuLatencyRequest&& other) noexcept {
  if (this != &other) {
    release();
    fd_ = other.fd_;
    other.fd_ = -1;
  }
  return *this;
}

void CpuLatencyRequest::release() noexcept {
  if (fd_ >= 0) {
    static_cast<void>(::close(fd_));  // closing withdraws the request; nothing to do on error
    fd_ = -1;
  }
}

}  // namespace loop
}  // namespace tcpest
