#include "tcpest/test/alloc_counter.hpp"

#include <cerrno>
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
thread_local std::size_t t_frees = 0U;
thread_local std::size_t t_fail_from = 0U;  // from this value of t_allocations on, allocations fail; 0: none
thread_local int t_scopes = 0;

// Counts an allocation; true when it is to fail.
inline bool note_allocation() noexcept {
  if (t_scopes > 0) {
    ++t_allocations;
    return t_fail_from != 0U && t_allocations >= t_fail_from;
  }
  return false;
}

#if TCPEST_COUNT_MALLOC
inline void note_free(const void* p) noexcept {
  if (t_scopes > 0 && p != nullptr) {
    ++t_frees;
  }
}
#endif
}  // namespace

namespace tcpest {
namespace test {

bool malloc_hook_active() noexcept { return TCPEST_COUNT_MALLOC != 0; }

AllocationScope::AllocationScope() noexcept : start_(t_allocations), frees_start_(t_frees) { ++t_scopes; }
AllocationScope::~AllocationScope() {
  --t_scopes;
  t_fail_from = 0U;
}
std::size_t AllocationScope::count() const noexcept { return t_allocations - start_; }
std::size_t AllocationScope::frees() const noexcept { return t_frees - frees_start_; }
void AllocationScope::fail_allocations_from(std::size_t nth) noexcept {
  t_fail_from = nth == 0U ? 0U : t_allocations + nth;
}

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
void __libc_free(void* p);                                       // NOLINT(bugprone-reserved-identifier)

// glibc lets a program replace malloc; these forward to glibc's own and count.
// A failed allocation sets errno as glibc's does: callers such as opendir
// report it through errno.
void* failed_allocation() noexcept {
  errno = ENOMEM;
  return nullptr;
}

void* malloc(std::size_t size) {
  return note_allocation() ? failed_allocation() : __libc_malloc(size);
}
void* calloc(std::size_t n, std::size_t size) {
  return note_allocation() ? failed_allocation() : __libc_calloc(n, size);
}
void* realloc(void* p, std::size_t size) {
  return note_allocation() ? failed_allocation() : __libc_realloc(p, size);
}
void* aligned_alloc(std::size_t alignment, std::size_t size) {
  return note_allocation() ? failed_allocation() : __libc_memalign(alignment, size);
}
void free(void* p) {
  note_free(p);
  __libc_free(p);
}
int posix_memalign(void** out, std::size_t alignment, std::size_t size) {
  void* p = note_allocation() ? nullptr : __libc_memalign(alignment, size);
  if (p == nullptr) {
    return ENOMEM;
  }
  *out = p;
  return 0;
}
}
#endif

// operator new is counted in every build (it reaches malloc only in some),
// once: it takes memory from glibc directly where malloc is ours.
namespace {
void* raw_malloc(std::size_t size) noexcept {
#if TCPEST_COUNT_MALLOC
  return __libc_malloc(size == 0U ? 1U : size);
#else
  return std::malloc(size == 0U ? 1U : size);  // NOLINT(cppcoreguidelines-no-malloc): the allocator itself
#endif
}

void* counted_new(std::size_t size) noexcept { return note_allocation() ? nullptr : raw_malloc(size); }

void* counted_new_aligned(std::size_t size, std::align_val_t alignment) noexcept {
  if (note_allocation()) {
    return nullptr;
  }
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
void* operator new(std::size_t size, const std::nothrow_t&) noexcept { return counted_new(size); }
void* operator new[](std::size_t size, const std::nothrow_t&) noexcept { return counted_new(size); }
void operator delete(void* p) noexcept { std::free(p); }
void operator delete[](void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t) noexcept { std::free(p); }
void* operator new(std::size_t size, std::align_val_t alignment) {
  void* p = counted_new_aligned(size, alignment);
  if (p == nullptr) {
    throw std::bad_alloc();
  }
  return p;
}
void* operator new[](std::size_t size, std::align_val_t alignment) { return operator new(size, alignment); }
void operator delete(void* p, std::align_val_t) noexcept { std::free(p); }
void operator delete[](void* p, std::align_val_t) noexcept { std::free(p); }
void operator delete(void* p, std::size_t, std::align_val_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t, std::align_val_t) noexcept { std::free(p); }
