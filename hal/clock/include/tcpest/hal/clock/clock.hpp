// Time for the loop: a monotonic clock in nanoseconds and sleeps to absolute
// deadlines. MonotonicClock is CLOCK_MONOTONIC with clock_nanosleep(TIMER_ABSTIME)
// (no drift: a deadline is computed from the start, never from "now + period");
// SimulatedClock only moves when told to, for deterministic tests and replay.
#pragma once

#include <cstdint>

#include "tcpest/common/result.hpp"

namespace tcpest {
namespace hal {

enum class ClockError : std::uint8_t {
  kNone = 0,
  kInterrupted,  // a signal arrived during the sleep (the caller decides whether to sleep again)
  kBadArgument,  // negative deadline or period
  kSystem,       // clock_gettime/clock_nanosleep failed otherwise
};
const char* to_string(ClockError error) noexcept;

constexpr std::int64_t kNsPerUs = 1000;
constexpr std::int64_t kNsPerMs = 1000 * kNsPerUs;
constexpr std::int64_t kNsPerS = 1000 * kNsPerMs;

class Clock {
 public:
  Clock() noexcept = default;
  virtual ~Clock() = default;
  Clock(const Clock&) = delete;
  Clock& operator=(const Clock&) = delete;
  Clock(Clock&&) = delete;
  Clock& operator=(Clock&&) = delete;

  // Nanoseconds on the monotonic time base (arbitrary origin, never goes back).
  virtual std::int64_t now_ns() const noexcept = 0;
  // Returns at or after deadline_ns (at once if it has passed), or kInterrupted.
  virtual Status<ClockError> sleep_until_ns(std::int64_t deadline_ns) noexcept = 0;
};

class MonotonicClock final : public Clock {
 public:
  std::int64_t now_ns() const noexcept override;
  Status<ClockError> sleep_until_ns(std::int64_t deadline_ns) noexcept override;
};

// A clock that stands still until advanced; sleep_until_ns jumps to the deadline.
class SimulatedClock final : public Clock {
 public:
  explicit SimulatedClock(std::int64_t start_ns = 0) noexcept : now_(start_ns) {}
  std::int64_t now_ns() const noexcept override { return now_; }
  Status<ClockError> sleep_until_ns(std::int64_t deadline_ns) noexcept override;
  void advance_ns(std::int64_t delta_ns) noexcept;

 private:
  std::int64_t now_;
};

// A fixed-period schedule with absolute deadlines: deadline n = start + n *
// period. When a cycle overruns past the next deadline(s), those periods are
// skipped (not run late in a burst) and counted as slips.
class PeriodicTimer {
 public:
  struct Tick {
    std::int64_t deadline_ns = 0;  // the deadline this wait was for
    std::int64_t woke_ns = 0;      // when the wait returned
    std::uint32_t slipped = 0U;    // periods skipped because they had already passed
  };

  PeriodicTimer(Clock& clock, std::int64_t period_ns) noexcept : clock_(clock), period_ns_(period_ns) {}
  // The first deadline is start_ns + period.
  void start(std::int64_t start_ns) noexcept;
  // Sleeps until the next deadline that has not passed. kInterrupted when a
  // signal cut the sleep short (the deadline is kept for the next call).
  Result<Tick, ClockError> wait_next() noexcept;
  std::int64_t period_ns() const noexcept { return period_ns_; }
  std::int64_t next_deadline_ns() const noexcept { return next_ns_; }
  std::uint64_t total_slips() const noexcept { return slips_; }

 private:
  Clock& clock_;
  std::int64_t period_ns_;
  std::int64_t next_ns_ = 0;
  std::uint64_t slips_ = 0U;
};

}  // namespace hal
}  // namespace tcpest
