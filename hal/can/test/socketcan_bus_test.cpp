// What can be checked without a CAN interface (this host may have no kernel
// CAN at all): arguments, the errno mapping, failures as values. The real
// socket paths run on vcan (tests/vcan).
#include "tcpest/hal/can/socketcan_bus.hpp"

#include <gtest/gtest.h>

#include <cerrno>
#include <cstring>

namespace tcpest {
namespace hal {
namespace {

// Verifies: REQ-HAL-003
TEST(SocketCanBus, UnopenedBusSaysSo) {
  SocketCanBus bus;
  can::Frame f;
  EXPECT_EQ(bus.send(f).error(), CanBusError::kNotOpen);
  ReceivedFrame rx[1];
  EXPECT_EQ(bus.receive(rx, 1).error(), CanBusError::kNotOpen);
  EXPECT_EQ(bus.state(), BusState::kDown);
  EXPECT_EQ(bus.fd(), -1);
}

// Verifies: REQ-HAL-003
TEST(SocketCanBus, BadArguments) {
  SocketCanBus bus;
  SocketCanConfig config;
  EXPECT_EQ(bus.open(nullptr, config).error(), CanBusError::kInvalidArgument);
  EXPECT_EQ(bus.open("", config).error(), CanBusError::kInvalidArgument);
  EXPECT_EQ(bus.open("an-interface-name-too-long", config).error(), CanBusError::kInvalidArgument);
  ASSERT_TRUE(config.rx_ids.push_back(0x800));
  EXPECT_EQ(bus.open("vcan0", config).error(), CanBusError::kInvalidArgument);
}

// Verifies: REQ-HAL-003
TEST(SocketCanBus, MissingInterfaceOrKernelSupportIsANamedError) {
  SocketCanBus bus;
  const auto opened = bus.open("tcpestnone0", SocketCanConfig{});
  ASSERT_FALSE(opened.ok());
  EXPECT_TRUE(opened.error() == CanBusError::kNotSupported || opened.error() == CanBusError::kNoSuchInterface)
      << to_string(opened.error());
  can::Frame f;
  EXPECT_FALSE(bus.send(f).ok());
  can::Frame too_long;
  too_long.length = 9;
  EXPECT_EQ(bus.send(too_long).error(), CanBusError::kBadFrame);
}

// Verifies: REQ-HAL-003
TEST(CanBusError, ErrnoMappedOnce) {
  EXPECT_EQ(error_from_errno(EAFNOSUPPORT), CanBusError::kNotSupported);
  EXPECT_EQ(error_from_errno(ENODEV), CanBusError::kNoSuchInterface);
  EXPECT_EQ(error_from_errno(ENETDOWN), CanBusError::kInterfaceDown);
  EXPECT_EQ(error_from_errno(ENOBUFS), CanBusError::kTxQueueFull);
  EXPECT_EQ(error_from_errno(EAGAIN), CanBusError::kTxQueueFull);
  EXPECT_EQ(error_from_errno(EPERM), CanBusError::kPermissionDenied);
  EXPECT_EQ(error_from_errno(EMFILE), CanBusError::kOutOfResources);
  EXPECT_EQ(error_from_errno(EIO), CanBusError::kIoError);
  for (int e = 0; e <= static_cast<int>(CanBusError::kIoError); ++e) {
    EXPECT_STRNE(to_string(static_cast<CanBusError>(e)), "unknown error");
  }
  for (int s = 0; s <= static_cast<int>(BusState::kDown); ++s) {
    EXPECT_STRNE(to_string(static_cast<BusState>(s)), "unknown");
  }
}

}  // namespace
}  // namespace hal
}  // namespace tcpest
