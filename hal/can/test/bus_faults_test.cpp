#include "tcpest/hal/can/bus_faults.hpp"

#include <gtest/gtest.h>

#include <vector>

#include "tcpest/hal/can/sim_bus.hpp"

namespace tcpest {
namespace hal {
namespace {

std::vector<can::EmcyMessage> cycle(can::Node& node, BusFaultMonitor& monitor, const CanBus& bus,
                                    std::int64_t now_us) {
  static_cast<void>(node.receive(nullptr, 0, now_us));
  EXPECT_TRUE(monitor.update(bus, node).ok());
  can::TxBatch batch;
  EXPECT_TRUE(node.collect(now_us, batch).ok());
  std::vector<can::EmcyMessage> emcy;
  for (const can::Frame& f : batch) {
    const auto decoded = can::decode_emcy(node.config().node_id, f);
    if (decoded.ok()) {
      emcy.push_back(decoded.value());
    }
  }
  return emcy;
}

// Verifies: REQ-HAL-004
TEST(BusFaultMonitor, ABusOffRecoveryIsOneCycleOfEmcy) {
  SimBus bus;
  can::Node node;
  can::NodeConfig config;
  config.start_operational = true;
  config.heartbeat_period_us = 0;
  ASSERT_TRUE(node.configure(config).ok());
  BusFaultMonitor monitor;
  SimEndpoint& endpoint = bus.endpoint(0);
  EXPECT_TRUE(cycle(node, monitor, endpoint, 0).empty());

  bus.set_bus_off(true);
  can::Frame f;
  f.id = 0x190;
  EXPECT_EQ(endpoint.send(f).error(), CanBusError::kBusOff);
  // The dropped frame is the sender's fault 12 (the loop's), not the monitor's.
  auto emcy = cycle(node, monitor, endpoint, 1);
  EXPECT_TRUE(emcy.empty());
  EXPECT_FALSE(node.fault_active(can::Fault::kCanTxDropped));

  bus.set_bus_off(false);
  emcy = cycle(node, monitor, endpoint, 2);
  ASSERT_EQ(emcy.size(), 1U);
  EXPECT_EQ(emcy[0].error_code, 0x8140U);  // bus-off recovered
  EXPECT_EQ(emcy[0].detail, 1U);           // the bus-off count
  emcy = cycle(node, monitor, endpoint, 3);
  ASSERT_EQ(emcy.size(), 1U);
  EXPECT_EQ(emcy[0].error_code, 0x0000U);
  EXPECT_EQ(emcy[0].fault_id, static_cast<std::uint8_t>(can::Fault::kCanBusOffRecovered));
}

// Verifies: REQ-CAN-011, REQ-HAL-004
TEST(BusFaultMonitor, KernelDropsAreAnOverrun) {
  SimBus bus;
  can::Node node;
  can::NodeConfig config;
  config.start_operational = true;
  config.heartbeat_period_us = 0;
  ASSERT_TRUE(node.configure(config).ok());
  BusFaultMonitor monitor;
  EXPECT_TRUE(cycle(node, monitor, bus.endpoint(1), 0).empty());
  can::Frame f;
  f.id = 0x210;
  for (std::size_t i = 0; i < SimEndpoint::kQueueCapacity + 5; ++i) {
    ASSERT_TRUE(bus.endpoint(0).send(f).ok());
  }
  const auto emcy = cycle(node, monitor, bus.endpoint(1), 1);
  ASSERT_EQ(emcy.size(), 1U);
  EXPECT_EQ(emcy[0].error_code, 0x8110U);
  EXPECT_EQ(emcy[0].detail, 5U);
}

}  // namespace
}  // namespace hal
}  // namespace tcpest
