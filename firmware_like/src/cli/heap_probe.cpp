#include "cli/heap_probe.hpp"

#include <atomic>

#if defined(__GLIBC__)
#include <malloc.h>
#endif

namespace tcpest {
namespace cli {

namespace {
std::atomic<const HeapProbe*> g_probe{nullptr};  // NOLINT(cppcoreguidelines-avoid-non-const-global-variables): set once by main or a test
}  // namespace

void set_heap_probe(const HeapProbe* probe) noexcept { g_probe.store(probe, std::memory_order_release); }

const HeapProbe* heap_probe() noexcept { return g_probe.load(std::memory_order_acquire); }

long long heap_bytes_in_use() noexcept {
#if defined(__GLIBC__) && (__GLIBC__ > 2 || (__GLIBC__ == 2 && __GLIBC_MINOR__ >= 33))
  const struct mallinfo2 info = ::mallinfo2();
  return static_cast<long long>(info.uordblks) + static_cast<long long>(info.hblkhd);
#else
  return -1;
#endif
}

}  // namespace cli
}  // namespace tcpest
