#include "tcpest/can_iface/node.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "tcpest/test/alloc_counter.hpp"

namespace tcpest {
namespace can {
namespace {

constexpr std::uint8_t kNode = 0x10;

Frame nmt(NmtCommand command, std::uint8_t node_id) {
  Frame frame;
  NmtMessage message;
  message.command = command;
  message.node_id = node_id;
  EXPECT_TRUE(encode_nmt(message, frame).ok());
  return frame;
}

Frame sync_frame() {
  Frame frame;
  EXPECT_TRUE(encode_sync(frame).ok());
  return frame;
}

Frame prior(std::uint8_t counter, double lambda_mm, EstimateStatus status = EstimateStatus::kValid) {
  EncoderPriorMessage message;
  message.lambda_mm = lambda_mm;
  message.phi_rad = 0.25;
  message.theta_rad = -0.5;
  message.status = status;
  message.counter = counter;
  Frame frame;
  EXPECT_TRUE(encode_encoder_prior(kNode, message, frame).ok());
  return frame;
}

Estimate sample_estimate() {
  Estimate e;
  e.status = EstimateStatus::kValid;
  e.tcp_x_mm = 1.5;
  e.tcp_y_mm = -2.25;
  e.tcp_z_mm = 40.0;
  e.lambda_mm = 20.0;
  e.phi_rad = 0.3;
  e.theta_rad = 0.8;
  e.x_ch_mm = -13.3;
  e.y_ch_mm = 6.2;
  e.psi_rad = 0.1745;
  e.mu_rad = 0.01;
  e.corners_detected = 12;
  e.corners_used = 11;
  e.rms_px = 0.5;
  e.latency_us = 8000;
  e.frame_counter = 42;
  return e;
}

class NodeTest : public ::testing::Test {
 protected:
  void SetUp() override { ASSERT_TRUE(node.configure(config).ok()); }

  std::vector<Frame> collect(std::int64_t now_us) {
    TxBatch batch;
    EXPECT_TRUE(node.collect(now_us, batch).ok());
    return std::vector<Frame>(batch.begin(), batch.end());
  }
  void feed(const Frame& frame, std::int64_t now_us) { static_cast<void>(node.receive(&frame, 1, now_us)); }
  void boot_and_start(std::int64_t now_us = 0) {
    static_cast<void>(collect(now_us));
    feed(nmt(NmtCommand::kStart, kNode), now_us);
    ASSERT_EQ(node.state(), NmtState::kOperational);
  }

  NodeConfig config{};
  Node node;
};

// Verifies: REQ-CAN-008
TEST_F(NodeTest, BootsUpIntoPreOperationalWithBootUpMessage) {
  EXPECT_EQ(node.state(), NmtState::kBootUp);
  const auto frames = collect(0);
  ASSERT_EQ(frames.size(), 1U);
  EXPECT_EQ(frames[0].id, 0x710U);
  EXPECT_EQ(frames[0].length, 1U);
  EXPECT_EQ(frames[0].data[0], 0x00);
  EXPECT_EQ(node.state(), NmtState::kPreOperational);
}

// Verifies: REQ-CAN-008
TEST_F(NodeTest, HeartbeatAtItsPeriodWithoutDriftOrBurst) {
  static_cast<void>(collect(0));
  std::vector<std::int64_t> times;
  for (std::int64_t t = 1000; t <= 1000000; t += 1000) {
    for (const Frame& f : collect(t)) {
      if (f.id == 0x710U) {
        EXPECT_EQ(f.data[0], 0x7F);
        times.push_back(t);
      }
    }
  }
  ASSERT_EQ(times.size(), 10U);
  for (std::size_t i = 0; i < times.size(); ++i) {
    EXPECT_EQ(times[i], static_cast<std::int64_t>(i + 1) * 100000);
  }
  // A stalled loop gets one heartbeat, not a burst.
  EXPECT_EQ(collect(5000000).size(), 1U);
  EXPECT_EQ(collect(5000001).size(), 0U);
  EXPECT_EQ(collect(5100000).size(), 1U);
}

// Verifies: REQ-CAN-008
TEST_F(NodeTest, NmtStateMachine) {
  static_cast<void>(collect(0));
  feed(nmt(NmtCommand::kStart, kNode), 1);
  EXPECT_EQ(node.state(), NmtState::kOperational);
  feed(nmt(NmtCommand::kStop, 0), 2);  // broadcast
  EXPECT_EQ(node.state(), NmtState::kStopped);
  feed(nmt(NmtCommand::kEnterPreOperational, kNode), 3);
  EXPECT_EQ(node.state(), NmtState::kPreOperational);
  feed(nmt(NmtCommand::kStart, kNode + 1), 4);  // another node
  EXPECT_EQ(node.state(), NmtState::kPreOperational);
  EXPECT_EQ(node.counters().nmt_other_node, 1U);
  feed(nmt(NmtCommand::kStart, kNode), 5);
  feed(nmt(NmtCommand::kResetCommunication, kNode), 6);
  EXPECT_EQ(node.state(), NmtState::kBootUp);
  // Commands during initialisation are ignored until the boot-up is out.
  feed(nmt(NmtCommand::kStart, kNode), 7);
  EXPECT_EQ(node.state(), NmtState::kBootUp);
  auto frames = collect(8);
  ASSERT_EQ(frames.size(), 1U);
  EXPECT_EQ(frames[0].data[0], 0x00);
  EXPECT_EQ(node.state(), NmtState::kPreOperational);
  feed(nmt(NmtCommand::kResetNode, 0), 9);
  EXPECT_EQ(node.state(), NmtState::kBootUp);
  frames = collect(10);
  ASSERT_EQ(frames.size(), 1U);
  EXPECT_EQ(node.state(), NmtState::kPreOperational);
}

// Verifies: REQ-CAN-008
TEST_F(NodeTest, BadNmtFramesCounted) {
  static_cast<void>(collect(0));
  Frame bad = nmt(NmtCommand::kStart, kNode);
  bad.length = 1;
  feed(bad, 1);
  Frame unknown = nmt(NmtCommand::kStart, kNode);
  unknown.data[0] = 0x55;
  feed(unknown, 2);
  EXPECT_EQ(node.state(), NmtState::kPreOperational);
  EXPECT_EQ(node.counters().nmt_wrong_length, 1U);
  EXPECT_EQ(node.counters().nmt_unknown_command, 1U);
}

// Verifies: REQ-CAN-004, REQ-CAN-007
TEST_F(NodeTest, PdosOnlyWhenOperationalInOrderWithCounters) {
  static_cast<void>(collect(0));
  ASSERT_TRUE(node.publish(sample_estimate()).ok());
  EXPECT_TRUE(collect(1000).empty());  // pre-operational: nothing, not queued
  feed(nmt(NmtCommand::kStart, kNode), 2000);
  EXPECT_TRUE(collect(3000).empty());
  for (int cycle = 0; cycle < 20; ++cycle) {
    ASSERT_TRUE(node.publish(sample_estimate()).ok());
    const auto frames = collect(4000 + cycle);
    ASSERT_EQ(frames.size(), 4U);
    EXPECT_EQ(frames[0].id, 0x190U);
    EXPECT_EQ(frames[1].id, 0x290U);
    EXPECT_EQ(frames[2].id, 0x390U);
    EXPECT_EQ(frames[3].id, 0x490U);
    const auto tcp = decode_tcp(kNode, frames[0]);
    const auto joints = decode_joints(kNode, frames[1]);
    ASSERT_TRUE(tcp.ok());
    ASSERT_TRUE(joints.ok());
    EXPECT_EQ(tcp.value().counter, cycle % 15);
    EXPECT_EQ(joints.value().counter, cycle % 15);
    EXPECT_EQ(tcp.value().status, EstimateStatus::kValid);
    EXPECT_NEAR(tcp.value().y_mm, -2.25, 1e-9);
    EXPECT_NEAR(joints.value().theta_rad, 0.8, 1e-9);
  }
  feed(nmt(NmtCommand::kStop, kNode), 5000);
  ASSERT_TRUE(node.publish(sample_estimate()).ok());
  EXPECT_TRUE(collect(6000).empty());
}

// Verifies: REQ-CAN-007
TEST_F(NodeTest, HeldRepeatsLastPoseAndInvalidWithoutOne) {
  boot_and_start();
  Estimate held;
  held.status = EstimateStatus::kHeld;
  held.frame_counter = 5;
  ASSERT_TRUE(node.publish(held).ok());
  auto frames = collect(1);
  ASSERT_EQ(frames.size(), 4U);
  EXPECT_EQ(decode_tcp(kNode, frames[0]).value().status, EstimateStatus::kInvalid);
  ASSERT_TRUE(node.publish(sample_estimate()).ok());
  static_cast<void>(collect(2));
  ASSERT_TRUE(node.publish(held).ok());
  frames = collect(3);
  const auto tcp = decode_tcp(kNode, frames[0]);
  EXPECT_EQ(tcp.value().status, EstimateStatus::kHeld);
  EXPECT_NEAR(tcp.value().x_mm, 1.5, 1e-9);
  EXPECT_EQ(decode_quality(kNode, frames[3]).value().frame_counter, 5U);
}

// Verifies: REQ-CAN-003
TEST_F(NodeTest, SaturatedEstimateSentAsInvalid) {
  boot_and_start();
  Estimate e = sample_estimate();
  e.tcp_z_mm = 1000.0;
  ASSERT_TRUE(node.publish(e).ok());
  const auto frames = collect(1);
  ASSERT_EQ(frames.size(), 4U);
  EXPECT_EQ(decode_tcp(kNode, frames[0]).value().status, EstimateStatus::kInvalid);
  EXPECT_EQ(decode_joints(kNode, frames[1]).value().status, EstimateStatus::kValid);
  EXPECT_EQ(node.counters().pdo_saturated, 1U);
}

// Verifies: REQ-CAN-012
TEST_F(NodeTest, SyncModeSendsLatestOncePerSyncCoalescingFloods) {
  config.sync_mode = true;
  ASSERT_TRUE(node.configure(config).ok());
  boot_and_start();
  ASSERT_TRUE(node.publish(sample_estimate()).ok());
  EXPECT_TRUE(collect(1).empty());  // no SYNC yet
  const auto summary = node.receive(std::vector<Frame>{sync_frame()}.data(), 1, 2);
  EXPECT_EQ(summary.syncs, 1U);
  EXPECT_EQ(collect(3).size(), 4U);
  EXPECT_TRUE(collect(4).empty());
  const std::vector<Frame> three(3, sync_frame());
  EXPECT_EQ(node.receive(three.data(), three.size(), 5).syncs, 3U);
  EXPECT_EQ(collect(6).size(), 4U);
  EXPECT_EQ(node.counters().sync_coalesced, 2U);
  Frame long_sync = sync_frame();
  long_sync.length = 3;
  feed(long_sync, 7);
  EXPECT_EQ(node.counters().sync_wrong_length, 1U);
}

// Verifies: REQ-CAN-010
TEST_F(NodeTest, EncoderPriorAcceptedAndRejectedAsTheProtocolSays) {
  config.prior_e2e = E2eConfig{2, 50000};
  ASSERT_TRUE(node.configure(config).ok());
  EXPECT_EQ(node.encoder_prior(0).error(), CanError::kNoData);
  static_cast<void>(collect(0));
  feed(prior(0, 10.0), 1);  // pre-operational: not a PDO state
  EXPECT_EQ(node.encoder_prior(1).error(), CanError::kNoData);
  feed(nmt(NmtCommand::kStart, kNode), 2);

  feed(prior(0, 10.0), 1000);
  auto p = node.encoder_prior(1000);
  ASSERT_TRUE(p.ok());
  EXPECT_NEAR(p.value().lambda_mm, 10.0, 1e-9);
  EXPECT_NEAR(p.value().phi_rad, 0.25, 1e-9);
  EXPECT_NEAR(p.value().theta_rad, -0.5, 1e-9);

  Frame corrupt = prior(1, 99.0);
  corrupt.data[0] ^= 0x40;
  feed(corrupt, 2000);
  EXPECT_NEAR(node.encoder_prior(2000).value().lambda_mm, 10.0, 1e-9);
  EXPECT_EQ(node.prior_counters().bad_crc, 1U);
  EXPECT_TRUE(node.fault_active(Fault::kPriorE2eError));
  {
    TxBatch batch;
    ASSERT_TRUE(node.collect(2001, batch).ok());
    ASSERT_EQ(batch.size(), 1U);
    const auto emcy = decode_emcy(kNode, batch[0]);
    EXPECT_EQ(emcy.value().error_code, 0x8200U);
    EXPECT_EQ(emcy.value().detail, 4U);  // docs/can-protocol.md: 4 = bad CRC
  }
  static_assert(static_cast<int>(CanError::kWrongLength) == 3 && static_cast<int>(CanError::kBadCrc) == 4 &&
                    static_cast<int>(CanError::kBadCounter) == 5 && static_cast<int>(CanError::kCounterRepeated) == 6 &&
                    static_cast<int>(CanError::kCounterJump) == 7,
                "EMCY detail numbers are part of the protocol");

  feed(prior(0, 98.0), 3000);  // repeated
  EXPECT_EQ(node.prior_counters().repeated, 1U);
  feed(prior(5, 97.0), 4000);  // jump of 5 > 2
  EXPECT_EQ(node.prior_counters().jumped, 1U);
  EXPECT_NEAR(node.encoder_prior(4000).value().lambda_mm, 10.0, 1e-9);
  feed(prior(6, 11.0), 5000);  // consecutive to the new reference
  EXPECT_NEAR(node.encoder_prior(5000).value().lambda_mm, 11.0, 1e-9);
  EXPECT_FALSE(node.fault_active(Fault::kPriorE2eError));
  Frame short_prior = prior(7, 12.0);
  short_prior.length = 6;
  feed(short_prior, 5500);
  EXPECT_EQ(node.prior_counters().bad_length, 1U);
  EXPECT_EQ(node.counters().prior_wrong_length, 1U);

  feed(prior(8, 12.0, EstimateStatus::kInvalid), 6000);  // sender says invalid
  EXPECT_EQ(node.counters().prior_invalid_status, 1U);
  EXPECT_NEAR(node.encoder_prior(6000).value().lambda_mm, 11.0, 1e-9);

  EXPECT_EQ(node.encoder_prior(6000 + 50001).error(), CanError::kStale);
  EXPECT_EQ(node.encoder_prior(6000 + 60000).error(), CanError::kStale);
  EXPECT_EQ(node.prior_counters().timeouts, 1U);
}

// Verifies: REQ-CAN-009
TEST_F(NodeTest, FaultsRaiseAndClearEmcyWithErrorRegister) {
  boot_and_start();
  ASSERT_TRUE(node.set_fault(Fault::kCameraTimeout, true, 1234).ok());
  ASSERT_TRUE(node.set_fault(Fault::kCameraTimeout, true, 99).ok());  // no new edge
  auto frames = collect(1);
  ASSERT_EQ(frames.size(), 1U);
  auto emcy = decode_emcy(kNode, frames[0]);
  ASSERT_TRUE(emcy.ok());
  EXPECT_EQ(emcy.value().error_code, 0xFF01U);
  EXPECT_EQ(emcy.value().error_register, 0x81U);
  EXPECT_EQ(emcy.value().fault_id, 1U);
  EXPECT_EQ(emcy.value().detail, 1234U);
  EXPECT_EQ(node.error_register(), 0x81U);
  ASSERT_TRUE(node.set_fault(Fault::kCameraTimeout, false, 0).ok());
  frames = collect(2);
  ASSERT_EQ(frames.size(), 1U);
  emcy = decode_emcy(kNode, frames[0]);
  EXPECT_EQ(emcy.value().error_code, 0x0000U);
  EXPECT_EQ(emcy.value().error_register, 0x00U);
  EXPECT_EQ(emcy.value().fault_id, 1U);
  EXPECT_FALSE(node.set_fault(static_cast<Fault>(0), true, 0).ok());
  EXPECT_FALSE(node.set_fault(static_cast<Fault>(kFaultCount + 1), true, 0).ok());
  EXPECT_EQ(node.set_fault(Fault::kCanRxOverrun, true, 0).error(), CanError::kNotAllowed);
  EXPECT_EQ(node.set_fault(Fault::kPriorTimeout, true, 0).error(), CanError::kNotAllowed);
  EXPECT_EQ(node.set_fault(Fault::kPriorE2eError, true, 0).error(), CanError::kNotAllowed);
}

// Verifies: REQ-CAN-009
TEST_F(NodeTest, BothEdgesInOneCycleEndInTheCurrentState) {
  boot_and_start();
  ASSERT_TRUE(node.set_fault(Fault::kTrackingLost, true, 1).ok());
  ASSERT_TRUE(node.set_fault(Fault::kTrackingLost, false, 0).ok());
  auto frames = collect(1);
  ASSERT_EQ(frames.size(), 2U);
  EXPECT_EQ(decode_emcy(kNode, frames[0]).value().error_code, 0xFF03U);
  EXPECT_EQ(decode_emcy(kNode, frames[1]).value().error_code, 0x0000U);
  ASSERT_TRUE(node.set_fault(Fault::kTrackingLost, true, 2).ok());
  static_cast<void>(collect(2));
  ASSERT_TRUE(node.set_fault(Fault::kTrackingLost, false, 0).ok());
  ASSERT_TRUE(node.set_fault(Fault::kTrackingLost, true, 3).ok());
  frames = collect(3);
  ASSERT_EQ(frames.size(), 2U);
  EXPECT_EQ(decode_emcy(kNode, frames[0]).value().error_code, 0x0000U);
  EXPECT_EQ(decode_emcy(kNode, frames[1]).value().error_code, 0xFF03U);
  EXPECT_EQ(decode_emcy(kNode, frames[1]).value().detail, 3U);
}

// Verifies: REQ-CAN-009
TEST_F(NodeTest, NoEmcyWhileStopped) {
  boot_and_start();
  feed(nmt(NmtCommand::kStop, kNode), 1);
  ASSERT_TRUE(node.set_fault(Fault::kSolverFailed, true, 0).ok());
  EXPECT_TRUE(collect(2).empty());
  EXPECT_EQ(node.counters().emcy_suppressed, 1U);
  EXPECT_TRUE(node.fault_active(Fault::kSolverFailed));
}

// Verifies: REQ-CAN-009
TEST_F(NodeTest, EveryFaultHasATableEntry) {
  for (std::uint8_t id = 1; id <= kFaultCount; ++id) {
    const FaultInfo* info = fault_info(static_cast<Fault>(id));
    ASSERT_NE(info, nullptr);
    EXPECT_EQ(static_cast<std::uint8_t>(info->fault), id);
    EXPECT_NE(info->error_code, 0U);
    EXPECT_NE(info->register_bits & kErrorRegisterGeneric, 0U);
  }
}

// Verifies: REQ-CAN-010
TEST_F(NodeTest, PriorTimeoutFaultWhenExpected) {
  config.prior_expected = true;
  config.prior_e2e = E2eConfig{2, 50000};
  ASSERT_TRUE(node.configure(config).ok());
  boot_and_start(0);
  EXPECT_TRUE(collect(10000).empty());
  auto frames = collect(60000);
  ASSERT_EQ(frames.size(), 1U);
  EXPECT_EQ(decode_emcy(kNode, frames[0]).value().error_code, 0x8250U);
  feed(prior(0, 1.0), 70000);
  frames = collect(70001);
  ASSERT_EQ(frames.size(), 1U);
  EXPECT_EQ(decode_emcy(kNode, frames[0]).value().error_code, 0x0000U);
}

// Verifies: REQ-CAN-011
TEST_F(NodeTest, FloodIsBoundedAndCounted) {
  boot_and_start();
  std::vector<Frame> flood(5000);
  for (std::size_t i = 0; i < flood.size(); ++i) {
    flood[i].id = 0x123;
    flood[i].length = 8;
  }
  const RxSummary summary = node.receive(flood.data(), flood.size(), 1);
  EXPECT_EQ(summary.processed, kMaxRxPerCycle);
  EXPECT_EQ(summary.dropped, 5000U - kMaxRxPerCycle);
  EXPECT_EQ(node.counters().rx_unknown_id, kMaxRxPerCycle);
  auto frames = collect(2);
  EXPECT_TRUE(node.fault_active(Fault::kCanRxOverrun));
  ASSERT_EQ(frames.size(), 1U);
  EXPECT_EQ(decode_emcy(kNode, frames[0]).value().error_code, 0x8110U);
  EXPECT_EQ(decode_emcy(kNode, frames[0]).value().detail, 5000U - kMaxRxPerCycle);
  // A sustained loss stays one active fault, no EMCY per cycle.
  static_cast<void>(node.receive(flood.data(), 1, 3));
  ASSERT_TRUE(node.report_rx_lost(7).ok());
  EXPECT_TRUE(collect(4).empty());
  EXPECT_TRUE(node.fault_active(Fault::kCanRxOverrun));
  static_cast<void>(node.receive(flood.data(), 1, 5));
  frames = collect(6);
  EXPECT_FALSE(node.fault_active(Fault::kCanRxOverrun));
  ASSERT_EQ(frames.size(), 1U);
  EXPECT_EQ(decode_emcy(kNode, frames[0]).value().error_code, 0x0000U);
}

// Verifies: REQ-CAN-011
TEST_F(NodeTest, UnknownIdsAndOwnIdsIgnored) {
  boot_and_start();
  Frame own;
  own.id = 0x190;  // our own TCP (another node with our ID)
  own.length = 8;
  feed(own, 1);
  Frame other_prior = prior(0, 1.0);
  other_prior.id = 0x211;
  feed(other_prior, 2);
  EXPECT_EQ(node.counters().rx_unknown_id, 2U);
  EXPECT_EQ(node.encoder_prior(3).error(), CanError::kNoData);
}

// Verifies: REQ-CAN-001
TEST_F(NodeTest, RejectsInvalidConfiguration) {
  NodeConfig bad;
  bad.node_id = 0;
  EXPECT_FALSE(node.configure(bad).ok());
  bad.node_id = 128;
  EXPECT_FALSE(node.configure(bad).ok());
  bad = NodeConfig{};
  bad.heartbeat_period_us = -1;
  EXPECT_FALSE(node.configure(bad).ok());
  bad = NodeConfig{};
  bad.prior_e2e.max_counter_step = 0;
  EXPECT_FALSE(node.configure(bad).ok());
}

// Verifies: REQ-CAN-007
TEST_F(NodeTest, TxBatchFullKeepsTheRestPending) {
  boot_and_start();
  std::size_t raised = 0;
  for (std::uint8_t id = 1; id <= kFaultCount; ++id) {
    if (!node_owned(static_cast<Fault>(id))) {
      ASSERT_TRUE(node.set_fault(static_cast<Fault>(id), true, id).ok());
      ++raised;
    }
  }
  TxBatch batch;
  for (int i = 0; i < 28; ++i) {
    ASSERT_TRUE(batch.push_back(Frame{}));
  }
  EXPECT_EQ(node.collect(1, batch).error(), CanError::kFull);
  TxBatch next;
  EXPECT_TRUE(node.collect(2, next).ok());
  EXPECT_EQ(batch.size() - 28U + next.size(), raised);
}

// Verifies: REQ-LOOP-006
TEST_F(NodeTest, CyclicPathDoesNotAllocate) {
  boot_and_start();
  const Frame in[3] = {prior(0, 1.0), sync_frame(), prior(1, 2.0)};
  TxBatch batch;
  test::AllocationScope scope;
  for (int cycle = 0; cycle < 100; ++cycle) {
    static_cast<void>(node.receive(in, 3, cycle * 1000));
    static_cast<void>(node.encoder_prior(cycle * 1000));
    static_cast<void>(node.publish(sample_estimate()));
    static_cast<void>(node.set_fault(Fault::kTrackingLost, (cycle % 7) == 0, 0));
    batch.clear();
    static_cast<void>(node.collect(cycle * 1000 + 500, batch));
  }
  EXPECT_EQ(scope.count(), 0U);
}

}  // namespace
}  // namespace can
}  // namespace tcpest
