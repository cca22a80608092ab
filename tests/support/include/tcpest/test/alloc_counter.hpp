// Counts heap allocations made by this thread's code between start() and
// stop(): every operator new, and (outside sanitizer builds, whose runtime owns
// malloc) every malloc/calloc/realloc/aligned_alloc. Tests wrap the code under
// test in an AllocationScope and assert the count is zero.
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
  // Allocations seen so far in this scope.
  std::size_t count() const noexcept;

 private:
  std::size_t start_;
};

}  // namespace test
}  // namespace tcpest
