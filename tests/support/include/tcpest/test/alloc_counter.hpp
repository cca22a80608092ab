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

// What an attempt did with memory running out from its nth allocation on.
struct OutOfMemoryOutcome {
  std::size_t nth = 0U;     // the first allocation that failed (1: the attempt's first)
  bool succeeded = false;   // the attempt's own answer
  std::size_t leaked = 0U;  // of the nth - 1 allocations before it, those not freed when the attempt returned
};

// Runs `attempt` (bool(): true when it succeeded; it releases everything
// it made before it returns, whatever the outcome) once with enough memory
// to count its allocations, then once with memory running out from each of
// them in turn, handing each outcome to `check`. Returns the count (0: the
// attempt failed with enough memory, or malloc is not hooked in this build
// and nothing was run out).
template <typename Attempt, typename Check>
std::size_t run_out_of_memory_at_each_allocation(Attempt&& attempt, Check&& check) {
  if (!malloc_hook_active()) {
    return 0U;
  }
  std::size_t needed = 0U;
  {
    AllocationScope scope;
    if (!attempt()) {
      return 0U;
    }
    needed = scope.count();
  }
  for (std::size_t nth = 1U; nth <= needed; ++nth) {
    OutOfMemoryOutcome outcome;
    outcome.nth = nth;
    {
      AllocationScope scope;
      scope.fail_allocations_from(nth);
      outcome.succeeded = attempt();
      const std::size_t freed = scope.frees();
      outcome.leaked = freed < nth - 1U ? nth - 1U - freed : 0U;
    }
    check(outcome);
  }
  return needed;
}

}  // namespace test
}  // namespace tcpest
