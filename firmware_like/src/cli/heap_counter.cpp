// The tcpest executable's heap counter for `tcpest bench --soak`: counting
// replacements of the global operator new and (outside sanitizer builds,
// whose runtime owns malloc) of malloc/calloc/realloc/aligned_alloc/
// posix_memalign, forwarding to glibc's own allocator. Linked into the
// executable only (firmware_like/CMakeLists.txt): the flight libraries keep
// the standard allocator, and the tests keep theirs (tests::AllocationScope).
//
// Why a replacement rather than mallinfo2() deltas: mallinfo2 sees bytes in
// use, so an allocation freed within the same cycle would pass unseen, and
// REQ-LOOP-006 is about allocations, not only about growth. glibc documents
// replacing malloc; the tests' counter does the same. The cost outside a
// soak is one relaxed atomic load per allocation.
#include <atomic>
#include <cerrno>
#include <cstdint>
#include <cstdlib>
#include <new>

#include "cli/heap_probe.hpp"

#if defined(__SANITIZE_ADDRESS__)
#define TCPEST_COUNT_MALLOC 0
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define TCPEST_COUNT_MALLOC 0
#endif
#endif
#ifndef TCPEST_COUNT_MALLOC
#define TCPEST_COUNT_MALLOC 1
#endif

namespace {
// Every thread's allocations count while armed: the soak wants none at all.
// Constant-initialised: malloc may run before any constructor.
std::atomic<bool> g_armed{false};                // NOLINT(cppcoreguidelines-avoid-non-const-global-variables): the allocator's state
std::atomic<std::uint64_t> g_allocations{0U};    // NOLINT(cppcoreguidelines-avoid-non-const-global-variables): idem

inline void note_allocation() noexcept {
  if (g_armed.load(std::memory_order_relaxed)) {
    g_allocations.fetch_add(1U, std::memory_order_relaxed);
  }
}

void arm() noexcept {
  g_allocations.store(0U, std::memory_order_relaxed);
  g_armed.store(true, std::memory_order_seq_cst);
}

std::uint64_t disarm() noexcept {
  g_armed.store(false, std::memory_order_seq_cst);
  return g_allocations.load(std::memory_order_relaxed);
}

const tcpest::cli::HeapProbe kProbe{TCPEST_COUNT_MALLOC != 0 ? "operator new and malloc" : "operator new only", arm,
                                    disarm};
}  // namespace

namespace tcpest {
namespace cli {
const HeapProbe* executable_heap_counter() noexcept { return &kProbe; }
}  // namespace cli
}  // namespace tcpest

#if TCPEST_COUNT_MALLOC
// The reserved names are glibc's own allocator entry points, which the
// counting malloc must reach without calling itself; the C library's
// declarations name their parameters with reserved names, these do not.
// NOLINTBEGIN(bugprone-reserved-identifier,cert-dcl37-c,cert-dcl51-cpp,readability-inconsistent-declaration-parameter-name)
extern "C" {
void* __libc_malloc(std::size_t size);
void* __libc_calloc(std::size_t n, std::size_t size);
void* __libc_realloc(void* p, std::size_t size);
void* __libc_memalign(std::size_t alignment, std::size_t size);
void __libc_free(void* p);

void* malloc(std::size_t size) {
  note_allocation();
  return __libc_malloc(size);
}
void* calloc(std::size_t n, std::size_t size) {
  note_allocation();
  return __libc_calloc(n, size);
}
void* realloc(void* p, std::size_t size) {
  note_allocation();
  return __libc_realloc(p, size);
}
void* aligned_alloc(std::size_t alignment, std::size_t size) {
  note_allocation();
  return __libc_memalign(alignment, size);
}
void free(void* p) { __libc_free(p); }
int posix_memalign(void** out, std::size_t alignment, std::size_t size) {
  note_allocation();
  void* p = __libc_memalign(alignment, size);
  if (p == nullptr) {
    return ENOMEM;
  }
  *out = p;
  return 0;
}
}
// NOLINTEND(bugprone-reserved-identifier,cert-dcl37-c,cert-dcl51-cpp,readability-inconsistent-declaration-parameter-name)
#endif

// operator new is counted in every build, once: where malloc is ours it
// takes memory from glibc directly.
namespace {
void* raw_malloc(std::size_t size) noexcept {
#if TCPEST_COUNT_MALLOC
  return __libc_malloc(size == 0U ? 1U : size);
#else
  return std::malloc(size == 0U ? 1U : size);  // NOLINT(cppcoreguidelines-no-malloc): the allocator itself
#endif
}

void* counted_new(std::size_t size) noexcept {
  note_allocation();
  return raw_malloc(size);
}

void* counted_new_aligned(std::size_t size, std::align_val_t alignment) noexcept {
  note_allocation();
  const std::size_t a = static_cast<std::size_t>(alignment) < sizeof(void*) ? sizeof(void*)
                                                                              : static_cast<std::size_t>(alignment);
  const std::size_t rounded = ((size == 0U ? 1U : size) + a - 1U) / a * a;  // aligned_alloc wants a multiple
#if TCPEST_COUNT_MALLOC
  return __libc_memalign(a, rounded);
#else
  return std::aligned_alloc(a, rounded);  // NOLINT(cppcoreguidelines-no-malloc): the allocator itself
#endif
}
}  // namespace

void* operator new(std::size_t size) {
  void* p = counted_new(size);
  if (p == nullptr) {
    throw std::bad_alloc();
  }
  return p;
}
void* operator new[](std::size_t size) { return operator new(size); }
void* operator new(std::size_t size, const std::nothrow_t& /*tag*/) noexcept { return counted_new(size); }
void* operator new[](std::size_t size, const std::nothrow_t& /*tag*/) noexcept { return counted_new(size); }
void operator delete(void* p) noexcept { std::free(p); }  // NOLINT(cppcoreguidelines-no-malloc): the allocator itself
void operator delete[](void* p) noexcept { std::free(p); }  // NOLINT(cppcoreguidelines-no-malloc): idem
void operator delete(void* p, std::size_t /*size*/) noexcept { std::free(p); }  // NOLINT(cppcoreguidelines-no-malloc): idem
void operator delete[](void* p, std::size_t /*size*/) noexcept { std::free(p); }  // NOLINT(cppcoreguidelines-no-malloc): idem
void* operator new(std::size_t size, std::align_val_t alignment) {
  void* p = counted_new_aligned(size, alignment);
  if (p == nullptr) {
    throw std::bad_alloc();
  }
  return p;
}
void* operator new[](std::size_t size, std::align_val_t alignment) { return operator new(size, alignment); }
void operator delete(void* p, std::align_val_t /*alignment*/) noexcept { std::free(p); }  // NOLINT(cppcoreguidelines-no-malloc): idem
void operator delete[](void* p, std::align_val_t /*alignment*/) noexcept { std::free(p); }  // NOLINT(cppcoreguidelines-no-malloc): idem
void operator delete(void* p, std::size_t /*size*/, std::align_val_t /*alignment*/) noexcept {
  std::free(p);  // NOLINT(cppcoreguidelines-no-malloc): idem
}
void operator delete[](void* p, std::size_t /*size*/, std::align_val_t /*alignment*/) noexcept {
  std::free(p);  // NOLINT(cppcoreguidelines-no-malloc): idem
}
