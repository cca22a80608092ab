// SpscQueue: full and empty are refused, not waited for; order is kept,
// also across threads and the wrap of the indices.
#include "tcpest/common/spsc_queue.hpp"

#include <gtest/gtest.h>

#include <cstdint>
#include <thread>

namespace tcpest {
namespace {

TEST(SpscQueue, AFullQueueRefusesAndAnEmptyOneGivesNothing) {
  SpscQueue<int> q;
  EXPECT_EQ(q.begin_push(), nullptr);  // not created
  EXPECT_FALSE(q.create(0U));
  ASSERT_TRUE(q.create(2U));
  EXPECT_EQ(q.capacity(), 2U);
  EXPECT_EQ(q.front(), nullptr);
  for (int i = 0; i < 2; ++i) {
    int* slot = q.begin_push();
    ASSERT_NE(slot, nullptr);
    *slot = i;
    q.commit_push();
  }
  EXPECT_EQ(q.begin_push(), nullptr);
  for (int expected = 0; expected < 2; ++expected) {
    const int* item = q.front();
    ASSERT_NE(item, nullptr);
    EXPECT_EQ(*item, expected);
    q.pop();
  }
  EXPECT_TRUE(q.empty());
}

TEST(SpscQueue, OneProducerAndOneConsumerSeeEveryItemInOrder) {
  SpscQueue<std::uint64_t> q;
  ASSERT_TRUE(q.create(3U));
  constexpr std::uint64_t kItems = 100000U;
  std::uint64_t expected = 0U;
  bool in_order = true;
  std::thread consumer([&] {
    while (expected < kItems) {
      const std::uint64_t* item = q.front();
      if (item == nullptr) {
        std::this_thread::yield();
        continue;
      }
      in_order = in_order && *item == expected;
      ++expected;
      q.pop();
    }
  });
  for (std::uint64_t i = 0; i < kItems;) {
    std::uint64_t* slot = q.begin_push();
    if (slot == nullptr) {
      std::this_thread::yield();
      continue;
    }
    *slot = i;
    q.commit_push();
    ++i;
  }
  consumer.join();
  EXPECT_TRUE(in_order);
  EXPECT_EQ(expected, kItems);
}

}  // namespace
}  // namespace tcpest
