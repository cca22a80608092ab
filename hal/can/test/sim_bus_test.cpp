#include "tcpest/hal/can/sim_bus.hpp"

#include <gtest/gtest.h>

#include <array>

#include "tcpest/test/alloc_counter.hpp"

namespace tcpest {
namespace hal {
namespace {

can::Frame make_frame(std::uint32_t id, std::uint8_t first) {
  can::Frame f;
  f.id = id;
  f.length = 8;
  for (std::uint8_t i = 0; i < 8; ++i) {
    f.data[i] = static_cast<std::uint8_t>(first + i);
  }
  return f;
}

// Verifies: REQ-HAL-007
TEST(SimBus, DeliversToOthersInOrderWithTime) {
  SimBus bus;
  bus.set_time_us(1000);
  ASSERT_TRUE(bus.endpoint(0).send(make_frame(0x190, 1)).ok());
  bus.set_time_us(2000);
  ASSERT_TRUE(bus.endpoint(0).send(make_frame(0x290, 2)).ok());
  std::array<ReceivedFrame, 8> rx{};
  auto got = bus.endpoint(1).receive(rx.data(), rx.size());
  ASSERT_TRUE(got.ok());
  ASSERT_EQ(got.value(), 2U);
  EXPECT_EQ(rx[0].frame, make_frame(0x190, 1));
  EXPECT_EQ(rx[0].timestamp_us, 1000);
  EXPECT_EQ(rx[1].frame.id, 0x290U);
  EXPECT_EQ(rx[1].timestamp_us, 2000);
  // The sender does not hear itself.
  EXPECT_EQ(bus.endpoint(0).receive(rx.data(), rx.size()).value(), 0U);
  EXPECT_EQ(bus.endpoint(0).stats().tx_frames, 2U);
  EXPECT_EQ(bus.endpoint(1).stats().rx_frames, 2U);
}

// Verifies: REQ-HAL-007
TEST(SimBus, ReceiveIsBoundedPerCall) {
  SimBus bus;
  for (int i = 0; i < 10; ++i) {
    ASSERT_TRUE(bus.endpoint(0).send(make_frame(0x100, static_cast<std::uint8_t>(i))).ok());
  }
  std::array<ReceivedFrame, 8> rx{};
  EXPECT_EQ(bus.endpoint(1).receive(rx.data(), 3).value(), 3U);
  EXPECT_EQ(rx[2].frame.data[0], 2U);
  EXPECT_EQ(bus.endpoint(1).receive(rx.data(), 8).value(), 7U);
}

// Verifies: REQ-HAL-007
TEST(SimBus, FiltersLikeTheKernel) {
  SimBus bus;
  const std::uint32_t ids[] = {0x000, 0x080, 0x210};
  ASSERT_TRUE(bus.endpoint(1).set_rx_ids(ids, 3).ok());
  ASSERT_TRUE(bus.endpoint(0).send(make_frame(0x210, 0)).ok());
  ASSERT_TRUE(bus.endpoint(0).send(make_frame(0x211, 0)).ok());
  std::array<ReceivedFrame, 4> rx{};
  EXPECT_EQ(bus.endpoint(1).receive(rx.data(), rx.size()).value(), 1U);
  EXPECT_EQ(rx[0].frame.id, 0x210U);
  const std::uint32_t bad[] = {0x800};
  EXPECT_FALSE(bus.endpoint(1).set_rx_ids(bad, 1).ok());
}

// Verifies: REQ-HAL-007
TEST(SimBus, DropCorruptDelayBusOff) {
  SimBus bus;
  std::array<ReceivedFrame, 8> rx{};
  bus.faults().drop_next = 1;
  ASSERT_TRUE(bus.endpoint(0).send(make_frame(0x100, 0)).ok());
  ASSERT_TRUE(bus.endpoint(0).send(make_frame(0x101, 0)).ok());
  EXPECT_EQ(bus.endpoint(1).receive(rx.data(), rx.size()).value(), 1U);
  EXPECT_EQ(rx[0].frame.id, 0x101U);
  EXPECT_EQ(bus.fault_counters().dropped, 1U);

  bus.faults().corrupt_next = 1;
  bus.faults().corrupt_byte = 3;
  bus.faults().corrupt_mask = 0x80;
  ASSERT_TRUE(bus.endpoint(0).send(make_frame(0x102, 0)).ok());
  ASSERT_EQ(bus.endpoint(1).receive(rx.data(), rx.size()).value(), 1U);
  EXPECT_EQ(rx[0].frame.data[3], 0x83U);
  EXPECT_EQ(bus.fault_counters().corrupted, 1U);

  bus.faults().delay_us = 500;
  bus.set_time_us(100);
  ASSERT_TRUE(bus.endpoint(0).send(make_frame(0x103, 0)).ok());
  bus.set_time_us(599);
  EXPECT_EQ(bus.endpoint(1).receive(rx.data(), rx.size()).value(), 0U);
  bus.set_time_us(600);
  ASSERT_EQ(bus.endpoint(1).receive(rx.data(), rx.size()).value(), 1U);
  EXPECT_EQ(rx[0].timestamp_us, 600);
  bus.faults().delay_us = 0;

  bus.faults().bus_off = true;
  EXPECT_EQ(bus.endpoint(0).send(make_frame(0x104, 0)).error(), CanBusError::kBusOff);
  EXPECT_EQ(bus.endpoint(1).state(), BusState::kBusOff);
  EXPECT_EQ(bus.endpoint(0).stats().tx_dropped, 1U);
  bus.faults().bus_off = false;
  EXPECT_TRUE(bus.endpoint(0).send(make_frame(0x104, 0)).ok());
  EXPECT_EQ(bus.endpoint(1).state(), BusState::kUp);

  bus.faults().drop_every = 2;
  int delivered = 0;
  for (int i = 0; i < 10; ++i) {
    ASSERT_TRUE(bus.endpoint(0).send(make_frame(0x105, 0)).ok());
  }
  auto got = bus.endpoint(1).receive(rx.data(), rx.size());
  delivered += static_cast<int>(got.value());
  got = bus.endpoint(1).receive(rx.data(), rx.size());
  delivered += static_cast<int>(got.value());
  EXPECT_EQ(delivered, 5 + 1);  // 5 of 10, plus the 0x104 still queued
}

// Verifies: REQ-HAL-007
TEST(SimBus, FloodOverflowsTheQueueAndIsCounted) {
  SimBus bus;
  for (std::size_t i = 0; i < SimEndpoint::kQueueCapacity + 100; ++i) {
    ASSERT_TRUE(bus.endpoint(0).send(make_frame(0x100, 0)).ok());
  }
  EXPECT_EQ(bus.endpoint(1).stats().rx_kernel_dropped, 100U);
}

// Verifies: REQ-HAL-007
TEST(SimBus, RejectsBadFramesAndDoesNotAllocate) {
  SimBus bus;
  can::Frame bad = make_frame(0x800, 0);
  EXPECT_EQ(bus.endpoint(0).send(bad).error(), CanBusError::kBadFrame);
  bad = make_frame(0x100, 0);
  bad.length = 9;
  EXPECT_EQ(bus.endpoint(0).send(bad).error(), CanBusError::kBadFrame);
  EXPECT_EQ(bus.endpoint(0).receive(nullptr, 1).error(), CanBusError::kInvalidArgument);
  std::array<ReceivedFrame, 8> rx{};
  test::AllocationScope scope;
  for (int i = 0; i < 100; ++i) {
    static_cast<void>(bus.endpoint(0).send(make_frame(0x100, 0)));
    static_cast<void>(bus.endpoint(1).receive(rx.data(), rx.size()));
  }
  EXPECT_EQ(scope.count(), 0U);
}

}  // namespace
}  // namespace hal
}  // namespace tcpest
