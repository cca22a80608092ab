// Counts heap allocations made by this thread's code between start() and
// stop(): every operator new, and (outside sanitizer builds, whose runtime owns
// malloc) every malloc/calloc/realloc/aligned_alloc. Tests wrap the code under
// test in an AllocationScope and assert the count is zero. Outside sanitizer
// builds a scope also counts the frees, and can make memory run out, so that
// a test can check that start-up code recovers from it without a leak.
#pragma once

#include <cstddef>

namespace tcpest {
namespace test {

// True when malloc itself is counted (false under AddressSanitizer).
bool malloc_hook_active() noexcept;

class AllocationScope {
 public:
  AllocationScope() noexcept;
  ~AllocationScope();
  AllocationScope(const AllocationScope&) = delete;
  AllocationScope& operator=(const AllocationScope&) = delete;
  // Allocations seen so far in this scope (the failed one included).
  std::size_t count() const noexcept;
  // Non-null pointers freed so far in this scope (free, operator delete;
  // only where malloc_hook_active()).
  std::size_t frees() const noexcept;
  // Memory runs out: from the nth allocation from now on (1: the next one)
  // until the scope's end, malloc and the nothrow operator new return null,
  // a throwing operator new throws. malloc only where malloc_hook_active().
  void fail_allocations_from(std::size_t nth) noexcept;

 private:
  std::size_t start_;
  std::size_t frees_start_;
};

}  // namespace test
}  // namespace tcpest
