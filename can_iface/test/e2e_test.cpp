#include "tcpest/can_iface/e2e.hpp"

#include <gtest/gtest.h>

namespace tcpest {
namespace can {
namespace {

// Verifies: REQ-CAN-004
TEST(AliveCounter, CountsZeroToFourteenAndWraps) {
  AliveCounter counter;
  for (int i = 0; i < 45; ++i) {
    EXPECT_EQ(counter.take(), i % 15);
  }
}

// Verifies: REQ-CAN-005
TEST(E2eConfig, Validates) {
  EXPECT_TRUE(validate(E2eConfig{}).ok());
  EXPECT_FALSE(validate(E2eConfig{0, 1000}).ok());
  EXPECT_FALSE(validate(E2eConfig{15, 1000}).ok());
  EXPECT_FALSE(validate(E2eConfig{3, 0}).ok());
}

// Verifies: REQ-CAN-005
TEST(E2eReceiver, AcceptsConsecutiveAndWrap) {
  E2eReceiver rx(E2eConfig{1, 1000000});
  std::int64_t t = 0;
  for (int i = 0; i < 40; ++i) {
    EXPECT_TRUE(rx.check_counter(static_cast<std::uint8_t>(i % 15), t += 1000).ok()) << i;
  }
  EXPECT_EQ(rx.counters().accepted, 40U);
}

// Verifies: REQ-CAN-005
TEST(E2eReceiver, RepeatIgnoredJumpIgnoredThenResynchronised) {
  E2eReceiver rx(E2eConfig{3, 1000000});
  EXPECT_TRUE(rx.check_counter(5, 0).ok());
  EXPECT_EQ(rx.check_counter(5, 1).error(), CanError::kCounterRepeated);
  EXPECT_TRUE(rx.check_counter(8, 2).ok());  // two lost: step 3 allowed
  EXPECT_EQ(rx.check_counter(12, 3).error(), CanError::kCounterJump);  // step 4
  EXPECT_TRUE(rx.check_counter(13, 4).ok());  // new reference 12
  EXPECT_EQ(rx.check_counter(10, 5).error(), CanError::kCounterJump);  // backwards = step 12
  EXPECT_EQ(rx.check_counter(15, 6).error(), CanError::kBadCounter);
  EXPECT_EQ(rx.counters().repeated, 1U);
  EXPECT_EQ(rx.counters().jumped, 2U);
  EXPECT_EQ(rx.counters().bad_counter, 1U);
  EXPECT_EQ(rx.counters().accepted, 3U);
}

// Verifies: REQ-CAN-005
TEST(E2eReceiver, TimeoutCountedOnceAndDropsReference) {
  E2eReceiver rx(E2eConfig{1, 100});
  EXPECT_EQ(rx.freshness(0).error(), CanError::kNoData);
  EXPECT_TRUE(rx.check_counter(3, 1000).ok());
  EXPECT_TRUE(rx.freshness(1100).ok());
  EXPECT_EQ(rx.freshness(1101).error(), CanError::kStale);
  EXPECT_EQ(rx.freshness(1200).error(), CanError::kStale);
  EXPECT_EQ(rx.counters().timeouts, 1U);
  // The counter it stopped at does not restart it (a frozen or replayed
  // frame); any other counter does.
  EXPECT_EQ(rx.check_counter(3, 1250).error(), CanError::kCounterRepeated);
  EXPECT_EQ(rx.freshness(1250).error(), CanError::kStale);
  EXPECT_TRUE(rx.check_counter(9, 1300).ok());
  EXPECT_TRUE(rx.freshness(1300).ok());
}

}  // namespace
}  // namespace can
}  // namespace tcpest
