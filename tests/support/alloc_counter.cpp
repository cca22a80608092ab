#include "tcpest/test/alloc_counter.hpp"

#include <cstdlib>
#include <new>

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
// Only the thread inside an AllocationScope counts: a test's other threads and
// GoogleTest's own bookkeeping outside the scope do not.
thread_local std::size_t t_allocations = 0U;
thread_local int t_scopes = 0;

inline void note_allocation() noexcept {
  if (t_scopes > 0) {
    ++t_allocations;
  }
}
}  // namespace

namespace tcpest {
namespace test {

bool malloc_hook_active() noexcept { return TCPEST_COUNT_MALLOC != 0; }

AllocationScope::AllocationScope() noexcept : start_(t_allocations) { ++t_scopes; }
AllocationScope::~AllocationScope() { --t_scopes; }
std::size_t AllocationScope::count() const noexcept { return t_allocations - start_; }

}  // namespace test
}  // namespace tcpest

#if TCPEST_COUNT_MALLOC
extern "C" {
// glibc's own allocator entry points: the reserved names are glibc's, and the
// counting malloc below must reach them without calling itself.
void* __libc_malloc(std::size_t size);                          // NOLINT(bugprone-reserved-identifier)
void* __libc_calloc(std::size_t n, std::size_t size);           // NOLINT(bugprone-reserved-identifier)
void* __libc_realloc(void* p, std::size_t size);                // NOLINT(bugprone-reserved-identifier)
void* __libc_memalign(std::size_t alignment, std::size_t size);  // NOLINT(bugprone-reserved-identifier)

// glibc lets a program replace malloc; these forward to glibc's own and count.
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
int posix_memalign(void** out, std::size_t alignment, std::size_t size) {
  note_allocation();
  void* p = __libc_memalign(alignment, size);
  if (p == nullptr) {
    return 12;  // ENOMEM
  }
  *out = p;
  return 0;
}
}
#endif

// operator new is counted in every build (it reaches malloc only in some).
void* operator new(std::size_t size) {
  note_allocation();
  void* p = std::malloc(size == 0U ? 1U : size);
  if (p == nullptr) {
    throw std::bad_alloc();
  }
  return p;
}
void* operator new[](std::size_t size) {
  note_allocation();
  void* p = std::malloc(size == 0U ? 1U : size);
  if (p == nullptr) {
    throw std::bad_alloc();
  }
  return p;
}
void* operator new(std::size_t size, const std::nothrow_t&) noexcept {
  note_allocation();
  return std::malloc(size == 0U ? 1U : size);
}
void* operator new[](std::size_t size, const std::nothrow_t&) noexcept {
  note_allocation();
  return std::malloc(size == 0U ? 1U : size);
}
void operator delete(void* p) noexcept { std::free(p); }
void operator delete[](void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t) noexcept { std::free(p); }
void* operator new(std::size_t size, std::align_val_t alignment) {
  note_allocation();
  void* p = nullptr;
  const std::size_t a = static_cast<std::size_t>(alignment) < sizeof(void*) ? sizeof(void*)
                                                                              : static_cast<std::size_t>(alignment);
  if (posix_memalign(&p, a, size == 0U ? 1U : size) != 0) {
    throw std::bad_alloc();
  }
  return p;
}
void* operator new[](std::size_t size, std::align_val_t alignment) { return operator new(size, alignment); }
void operator delete(void* p, std::align_val_t) noexcept { std::free(p); }
void operator delete[](void* p, std::align_val_t) noexcept { std::free(p); }
void operator delete(void* p, std::size_t, std::align_val_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t, std::align_val_t) noexcept { std::free(p); }
