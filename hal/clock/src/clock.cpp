#include "tcpest/hal/clock/clock.hpp"

#include <cerrno>
#include <ctime>

namespace tcpest {
namespace hal {

const char* to_string(ClockError error) noexcept {
  switch (error) {
    case ClockError::kNone:
      return "ok";
    case ClockError::kInterrupted:
      return "interrupted by a signal";
    case ClockError::kBadArgument:
      return "bad argument";
    case ClockError::kSystem:
      return "system clock error";
  }
  return "unknown clock error";
}

std::int64_t MonotonicClock::now_ns() const noexcept {
  timespec ts{};
  // CLOCK_MONOTONIC with a valid pointer cannot fail (EINVAL/EFAULT only).
  static_cast<void>(clock_gettime(CLOCK_MONOTONIC, &ts));
  return static_cast<std::int64_t>(ts.tv_sec) * kNsPerS + static_cast<std::int64_t>(ts.tv_nsec);
}

Status<ClockError> MonotonicClock::sleep_until_ns(std::int64_t deadline_ns) noexcept {
  if (deadline_ns < 0) {
    return Status<ClockError>::failure(ClockError::kBadArgument);
  }
  timespec ts{};
  ts.tv_sec = static_cast<time_t>(deadline_ns / kNsPerS);
  ts.tv_nsec = static_cast<long>(deadline_ns % kNsPerS);
  const int rc = clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr);  // returns the error, not errno
  if (rc == 0) {
    return ok_status<ClockError>();
  }
  return Status<ClockError>::failure(rc == EINTR ? ClockError::kInterrupted : ClockError::kSystem);
}

Status<ClockError> SimulatedClock::sleep_until_ns(std::int64_t deadline_ns) noexcept {
  if (deadline_ns < 0) {
    return Status<ClockError>::failure(ClockError::kBadArgument);
  }
  if (deadline_ns > now_) {
    now_ = deadline_ns;
  }
  return ok_status<ClockError>();
}

void SimulatedClock::advance_ns(std::int64_t delta_ns) noexcept {
  if (delta_ns > 0) {
    now_ += delta_ns;
  }
}

void PeriodicTimer::start(std::int64_t start_ns) noexcept {
  next_ns_ = start_ns + period_ns_;
  slips_ = 0U;
}

Result<PeriodicTimer::Tick, ClockError> PeriodicTimer::wait_next() noexcept {
  if (period_ns_ <= 0) {
    return Result<Tick, ClockError>::failure(ClockError::kBadArgument);
  }
  Tick tick;
  const std::int64_t now = clock_.now_ns();
  if (now > next_ns_) {
    // Deadlines already passed are skipped in one step (division, not a loop);
    // a deadline equal to now is still met.
    const std::int64_t missed = (now - next_ns_ + period_ns_ - 1) / period_ns_;
    if (missed > 0) {
      next_ns_ += missed * period_ns_;
      tick.slipped = static_cast<std::uint32_t>(missed > 0xFFFFFFFFLL ? 0xFFFFFFFFLL : missed);
      slips_ += static_cast<std::uint64_t>(missed);
    }
  }
  const auto slept = clock_.sleep_until_ns(next_ns_);
  if (!slept.ok()) {
    return Result<Tick, ClockError>::failure(slept.error());
  }
  tick.deadline_ns = next_ns_;
  tick.woke_ns = clock_.now_ns();
  next_ns_ += period_ns_;
  return Result<Tick, ClockError>::success(tick);
}

}  // namespace hal
}  // namespace tcpest
