#include "tcpest/hal/clock/clock.hpp"

#include <gtest/gtest.h>

namespace tcpest {
namespace hal {
namespace {

// Verifies: REQ-HAL-006
TEST(MonotonicClock, NeverGoesBackAndSleepsToAbsoluteDeadlines) {
  MonotonicClock clock;
  const std::int64_t t0 = clock.now_ns();
  const std::int64_t deadline = t0 + 2 * kNsPerMs;
  ASSERT_TRUE(clock.sleep_until_ns(deadline).ok());
  EXPECT_GE(clock.now_ns(), deadline);
  // A deadline in the past returns at once.
  ASSERT_TRUE(clock.sleep_until_ns(t0).ok());
  EXPECT_FALSE(clock.sleep_until_ns(-1).ok());
}

// Verifies: REQ-HAL-006
TEST(SimulatedClock, MovesOnlyWhenTold) {
  SimulatedClock clock(100);
  EXPECT_EQ(clock.now_ns(), 100);
  ASSERT_TRUE(clock.sleep_until_ns(50).ok());
  EXPECT_EQ(clock.now_ns(), 100);
  ASSERT_TRUE(clock.sleep_until_ns(400).ok());
  EXPECT_EQ(clock.now_ns(), 400);
  clock.advance_ns(25);
  EXPECT_EQ(clock.now_ns(), 425);
}

// Verifies: REQ-LOOP-003, REQ-HAL-006
TEST(PeriodicTimer, DeadlinesAreAbsoluteAndDoNotDrift) {
  SimulatedClock clock(0);
  PeriodicTimer timer(clock, 40 * kNsPerMs);
  timer.start(0);
  for (int n = 1; n <= 100; ++n) {
    clock.advance_ns(3 * kNsPerMs);  // work of the cycle
    const auto tick = timer.wait_next();
    ASSERT_TRUE(tick.ok());
    EXPECT_EQ(tick.value().deadline_ns, n * 40 * kNsPerMs);
    EXPECT_EQ(tick.value().slipped, 0U);
  }
}

// Verifies: REQ-LOOP-003, REQ-HAL-006
TEST(PeriodicTimer, OverrunsSkipMissedPeriodsAndCountThem) {
  SimulatedClock clock(0);
  PeriodicTimer timer(clock, 10);
  timer.start(0);
  ASSERT_TRUE(timer.wait_next().ok());  // t = 10
  clock.advance_ns(35);                 // t = 45: deadlines 20, 30, 40 missed
  const auto tick = timer.wait_next();
  ASSERT_TRUE(tick.ok());
  EXPECT_EQ(tick.value().slipped, 3U);
  EXPECT_EQ(tick.value().deadline_ns, 50);
  EXPECT_EQ(timer.total_slips(), 3U);
}

// Verifies: REQ-HAL-006
TEST(PeriodicTimer, ZeroPeriodIsAnError) {
  SimulatedClock clock(0);
  PeriodicTimer timer(clock, 0);
  timer.start(0);
  EXPECT_FALSE(timer.wait_next().ok());
}

// A clock whose sleeps a signal interrupts while `interrupt` is set.
class InterruptedClock final : public Clock {
 public:
  std::int64_t now_ns() const noexcept override { return now_; }
  Status<ClockError> sleep_until_ns(std::int64_t deadline_ns) noexcept override {
    if (interrupt) {
      return Status<ClockError>::failure(ClockError::kInterrupted);
    }
    now_ = deadline_ns > now_ ? deadline_ns : now_;
    return ok_status<ClockError>();
  }
  bool interrupt = true;

 private:
  std::int64_t now_ = 0;
};

// Bad input is an error value with a name; simulated time never goes back.
// Verifies: REQ-HAL-006
TEST(Clocks, BadInputIsAnErrorValue) {
  SimulatedClock clock(100);
  const auto refused = clock.sleep_until_ns(-1);
  ASSERT_FALSE(refused.ok());
  EXPECT_EQ(refused.error(), ClockError::kBadArgument);
  clock.advance_ns(-50);
  EXPECT_EQ(clock.now_ns(), 100);
  // A timer whose sleep a signal cuts short passes that on (the loop stops
  // cleanly on it), and waits for the same deadline next time.
  InterruptedClock interrupted;
  PeriodicTimer timer(interrupted, 10);
  timer.start(0);
  const auto tick = timer.wait_next();
  ASSERT_FALSE(tick.ok());
  EXPECT_EQ(tick.error(), ClockError::kInterrupted);
  interrupted.interrupt = false;
  const auto next = timer.wait_next();
  ASSERT_TRUE(next.ok());
  EXPECT_EQ(next.value().deadline_ns, 10);
  const ClockError errors[] = {ClockError::kNone, ClockError::kInterrupted, ClockError::kBadArgument,
                               ClockError::kSystem};
  for (std::size_t i = 0; i < 4U; ++i) {
    for (std::size_t j = i + 1U; j < 4U; ++j) {
      EXPECT_STRNE(to_string(errors[i]), to_string(errors[j]));
    }
  }
  EXPECT_STREQ(to_string(static_cast<ClockError>(200)), "unknown clock error");
}

}  // namespace
}  // namespace hal
}  // namespace tcpest
