// can::Receiver, the controllers' side, fed with what can::Node sends (round
// trip), then with damaged streams: a bad CRC, skipped and repeated
// counters, a silent node, a reboot. Also the heartbeat's timing as a
// controller sees it on the 25 Hz cycle (docs/can-protocol.md, HEARTBEAT).
#include "tcpest/can_iface/receiver.hpp"

#include <gtest/gtest.h>

#include <vector>

#include "tcpest/can_iface/node.hpp"
#include "tcpest/test/alloc_counter.hpp"

namespace tcpest {
namespace can {
namespace {

constexpr std::uint8_t kNode = 0x10;
constexpr std::int64_t kCycleUs = 40000;  // 25 Hz

Estimate estimate_for(int cycle) {
  Estimate e;
  e.status = cycle % 5 == 4 ? EstimateStatus::kDegraded : EstimateStatus::kValid;
  e.tcp_x_mm = -13.3 + 0.25 * cycle;
  e.tcp_y_mm = 6.21 - 0.5 * cycle;
  e.tcp_z_mm = 45.68 + 0.01 * cycle;
  e.lambda_mm = 15.5 + 0.1 * cycle;
  e.phi_rad = 0.125;
  e.theta_rad = -0.25;
  e.x_ch_mm = 1.0;
  e.y_ch_mm = -1.0;
  e.psi_rad = 0.01;
  e.mu_rad = -0.02;
  e.corners_detected = 9;
  e.corners_used = 8;
  e.rms_px = 0.75;
  e.latency_us = 9000;
  e.frame_counter = static_cast<std::uint16_t>(cycle);
  return e;
}

// A node started by NMT, publishing one estimate per 40 ms cycle; returns
// every frame it sent with its send time.
struct Sent {
  Frame frame;
  std::int64_t t_us;
};

std::vector<Sent> run_node(int cycles, std::int64_t period_us = kCycleUs) {
  Node node;
  EXPECT_TRUE(node.configure(NodeConfig{}).ok());
  std::vector<Sent> sent;
  TxBatch batch;
  for (int cycle = 0; cycle < cycles; ++cycle) {
    const std::int64_t now = cycle * period_us;
    if (cycle == 1) {
      Frame start;
      EXPECT_TRUE(encode_nmt(NmtMessage{NmtCommand::kStart, kNode}, start).ok());
      static_cast<void>(node.receive(&start, 1, now));
    }
    EXPECT_TRUE(node.publish(estimate_for(cycle)).ok());
    batch.clear();
    EXPECT_TRUE(node.collect(now, batch).ok());
    for (const Frame& f : batch) {
      sent.push_back(Sent{f, now});
    }
  }
  return sent;
}

// Verifies: REQ-CAN-015
TEST(Receiver, DecodesWhatTheNodeSends) {
  const std::vector<Sent> sent = run_node(50);
  Receiver rx;
  int tcps = 0;
  for (const Sent& s : sent) {
    const auto got = rx.receive(s.frame, s.t_us + 100);
    ASSERT_TRUE(got.ok()) << to_string(got.error()) << " id " << s.frame.id;
    if (got.value() == Message::kTcp) {
      // Cycle 0 is pre-operational (no PDOs): the first TCP is cycle 1's.
      const Estimate e = estimate_for(tcps + 1);
      const auto tcp = rx.tcp();
      ASSERT_TRUE(tcp.ok());
      EXPECT_NEAR(tcp.value().value.x_mm, e.tcp_x_mm, 0.005);
      EXPECT_NEAR(tcp.value().value.y_mm, e.tcp_y_mm, 0.005);
      EXPECT_NEAR(tcp.value().value.z_mm, e.tcp_z_mm, 0.005);
      EXPECT_EQ(rx.estimate_status(s.t_us + 100), e.status);
      ++tcps;
    }
  }
  EXPECT_EQ(tcps, 49);
  const ReceiverCounters& c = rx.counters();
  EXPECT_EQ(c.frames, sent.size());
  EXPECT_EQ(c.decoded, sent.size());
  EXPECT_EQ(c.e2e_failures, 0U);
  EXPECT_EQ(c.counter_jumps, 0U);
  EXPECT_EQ(c.stale_events, 0U);
  EXPECT_EQ(c.boot_ups, 1U);
  EXPECT_EQ(rx.tcp_e2e().accepted, 49U);
  EXPECT_EQ(rx.joints_e2e().accepted, 49U);
  ASSERT_TRUE(rx.nmt_state().ok());
  EXPECT_EQ(rx.nmt_state().value().value, NmtState::kOperational);
  ASSERT_TRUE(rx.joints().ok());
  EXPECT_NEAR(rx.joints().value().value.lambda_mm, estimate_for(49).lambda_mm, 0.005);
  ASSERT_TRUE(rx.quality().ok());
  EXPECT_EQ(rx.quality().value().value.corners_used, 8U);
  EXPECT_EQ(rx.quality().value().value.frame_counter, 49U);
  ASSERT_TRUE(rx.mechanical().ok());
  EXPECT_NEAR(rx.mechanical().value().value.mu_rad, -0.02, 0.00005);
  EXPECT_FALSE(rx.last_emcy().ok());
}

Frame first_tcp(const std::vector<Sent>& sent, std::size_t skip = 0U) {
  for (const Sent& s : sent) {
    if (s.frame.id == tcp_id(kNode)) {
      if (skip == 0U) {
        return s.frame;
      }
      --skip;
    }
  }
  ADD_FAILURE() << "no TCP frame";
  return Frame{};
}

// Verifies: REQ-CAN-015
TEST(Receiver, RefusesACorruptedCrcAndKeepsTheLastGoodValue) {
  const std::vector<Sent> sent = run_node(4);
  Receiver rx;
  ASSERT_TRUE(rx.receive(first_tcp(sent, 0), 0).ok());
  Frame bad = first_tcp(sent, 1);
  bad.data[0] = static_cast<std::uint8_t>(bad.data[0] ^ 0x01U);  // one bit flipped on the wire
  const auto got = rx.receive(bad, 40000);
  ASSERT_FALSE(got.ok());
  EXPECT_EQ(got.error(), CanError::kBadCrc);
  EXPECT_EQ(rx.counters().e2e_failures, 1U);
  EXPECT_EQ(rx.tcp_e2e().bad_crc, 1U);
  EXPECT_NEAR(rx.tcp().value().value.x_mm, estimate_for(1).tcp_x_mm, 0.005);
  // The sequence goes on: the next one is a step of 2, inside the window.
  EXPECT_TRUE(rx.receive(first_tcp(sent, 2), 80000).ok());
  // A wrong length is an E2E failure too.
  Frame short_frame = first_tcp(sent, 2);
  short_frame.length = 7U;
  EXPECT_EQ(rx.receive(short_frame, 80001).error(), CanError::kWrongLength);
  EXPECT_EQ(rx.counters().e2e_failures, 2U);
}

// Verifies: REQ-CAN-015
TEST(Receiver, RefusesARepeatedCounterAndCountsAJump) {
  Receiver rx;
  auto tcp_frame = [](std::uint8_t counter) {
    TcpMessage m;
    m.x_mm = counter;
    m.status = EstimateStatus::kValid;
    m.counter = counter;
    Frame f;
    EXPECT_TRUE(encode_tcp(kNode, m, f).ok());
    return f;
  };
  ASSERT_TRUE(rx.receive(tcp_frame(0), 0).ok());
  EXPECT_EQ(rx.receive(tcp_frame(0), 1000).error(), CanError::kCounterRepeated);
  EXPECT_TRUE(rx.receive(tcp_frame(3), 2000).ok());  // two lost: within the default window of 3
  EXPECT_EQ(rx.receive(tcp_frame(10), 3000).error(), CanError::kCounterJump);
  EXPECT_TRUE(rx.receive(tcp_frame(11), 4000).ok());  // the jump became the reference
  EXPECT_EQ(rx.receive(tcp_frame(9), 5000).error(), CanError::kCounterJump);  // backwards
  EXPECT_TRUE(rx.receive(tcp_frame(12), 5500).ok());
  EXPECT_TRUE(rx.receive(tcp_frame(14), 6000).ok());
  EXPECT_TRUE(rx.receive(tcp_frame(0), 7000).ok());  // 14 -> 0 wraps
  EXPECT_EQ(rx.counters().e2e_failures, 1U);
  EXPECT_EQ(rx.counters().counter_jumps, 2U);
  EXPECT_EQ(rx.tcp_e2e().repeated, 1U);
  EXPECT_EQ(rx.tcp_e2e().jumped, 2U);
  EXPECT_NEAR(rx.tcp().value().value.x_mm, 0.0, 1e-9);
}

// Verifies: REQ-CAN-015
TEST(Receiver, ASilentNodeMakesTheEstimateStaleOnce) {
  const std::vector<Sent> sent = run_node(6);
  Receiver rx;  // timeout 100 ms
  std::int64_t last_tcp_us = 0;
  for (const Sent& s : sent) {
    ASSERT_TRUE(rx.receive(s.frame, s.t_us).ok());
    if (s.frame.id == tcp_id(kNode)) {
      last_tcp_us = s.t_us;
    }
  }
  EXPECT_NE(rx.estimate_status(last_tcp_us + 100000), EstimateStatus::kInvalid);
  EXPECT_FALSE(rx.stale(last_tcp_us + 100000));
  EXPECT_TRUE(rx.stale(last_tcp_us + 100001));
  EXPECT_EQ(rx.estimate_status(last_tcp_us + 100001), EstimateStatus::kInvalid);
  rx.update(last_tcp_us + 100001);
  rx.update(last_tcp_us + 500000);
  EXPECT_EQ(rx.counters().stale_events, 1U);
  // Heartbeats alone do not make the estimate fresh again.
  Frame heartbeat;
  ASSERT_TRUE(encode_heartbeat(kNode, NmtState::kOperational, heartbeat).ok());
  ASSERT_TRUE(rx.receive(heartbeat, last_tcp_us + 600000).ok());
  EXPECT_EQ(rx.estimate_status(last_tcp_us + 600000), EstimateStatus::kInvalid);
  EXPECT_EQ(rx.counters().stale_events, 1U);
  // The next TCP is accepted without a sequence reference, whatever its counter.
  TcpMessage m;
  m.status = EstimateStatus::kHeld;
  m.counter = 13U;
  Frame f;
  ASSERT_TRUE(encode_tcp(kNode, m, f).ok());
  ASSERT_TRUE(rx.receive(f, last_tcp_us + 700000).ok());
  EXPECT_EQ(rx.estimate_status(last_tcp_us + 700000), EstimateStatus::kHeld);
  EXPECT_EQ(rx.counters().counter_jumps, 0U);
}

// Verifies: REQ-CAN-015
TEST(Receiver, NoTcpYetIsInvalidAndABootUpRestartsTheCounters) {
  Receiver rx;
  EXPECT_EQ(rx.estimate_status(0), EstimateStatus::kInvalid);
  EXPECT_EQ(rx.tcp().error(), CanError::kNoData);
  EXPECT_EQ(rx.nmt_state().error(), CanError::kNoData);
  // A node that was reset starts its counters again at 0: not a jump.
  const std::vector<Sent> first = run_node(10);
  for (const Sent& s : first) {
    ASSERT_TRUE(rx.receive(s.frame, s.t_us).ok());
  }
  for (const Sent& s : run_node(4)) {
    ASSERT_TRUE(rx.receive(s.frame, 400000 + s.t_us).ok()) << s.frame.id;
  }
  EXPECT_EQ(rx.counters().boot_ups, 2U);
  EXPECT_EQ(rx.counters().counter_jumps, 0U);
}

// Verifies: REQ-CAN-015
TEST(Receiver, EmcyOtherNodesAndBadFrames) {
  Receiver rx;
  Frame emcy;
  ASSERT_TRUE(encode_emcy(kNode, EmcyMessage{0xFF01U, 0x81U, 1U, 250U}, emcy).ok());
  ASSERT_TRUE(rx.receive(emcy, 10).ok());
  ASSERT_TRUE(rx.last_emcy().ok());
  EXPECT_EQ(rx.last_emcy().value().value.fault_id, 1U);
  EXPECT_EQ(rx.last_emcy().value().value.detail, 250U);
  ASSERT_TRUE(encode_emcy(kNode, EmcyMessage{0x0000U, 0x00U, 1U, 0U}, emcy).ok());
  ASSERT_TRUE(rx.receive(emcy, 20).ok());
  EXPECT_EQ(rx.counters().emcy_raised, 1U);
  EXPECT_EQ(rx.counters().emcy_cleared, 1U);
  Frame other;
  ASSERT_TRUE(encode_heartbeat(kNode + 1, NmtState::kOperational, other).ok());
  EXPECT_EQ(rx.receive(other, 30).error(), CanError::kUnknownId);
  Frame bad_state;
  ASSERT_TRUE(encode_heartbeat(kNode, NmtState::kOperational, bad_state).ok());
  bad_state.data[0] = 0x42U;
  EXPECT_FALSE(rx.receive(bad_state, 40).ok());
  Frame short_quality;
  ASSERT_TRUE(encode_quality(kNode, QualityMessage{}, short_quality).ok());
  short_quality.length = 4U;
  EXPECT_EQ(rx.receive(short_quality, 50).error(), CanError::kWrongLength);
  EXPECT_EQ(rx.counters().other_id, 1U);
  EXPECT_EQ(rx.counters().malformed, 2U);
  EXPECT_EQ(rx.counters().e2e_failures, 0U);
  ReceiverConfig bad;
  bad.node_id = 0U;
  EXPECT_EQ(rx.configure(bad).error(), CanError::kInvalidArgument);
  bad.node_id = kNode;
  bad.e2e.timeout_us = 0;
  EXPECT_EQ(rx.configure(bad).error(), CanError::kInvalidArgument);
}

// Verifies: REQ-CAN-015
TEST(Receiver, ReceivingDoesNotAllocate) {
  const std::vector<Sent> sent = run_node(30);
  Receiver rx;
  test::AllocationScope scope;
  for (const Sent& s : sent) {
    static_cast<void>(rx.receive(s.frame, s.t_us));
    static_cast<void>(rx.estimate_status(s.t_us));
  }
  EXPECT_EQ(scope.count(), 0U);
}

// The heartbeat keeps the grid k x 100 ms from the boot-up and goes out at
// the first cycle at or after each due time: on a 25 Hz cycle a controller
// sees gaps of 80 and 120 ms, never more than the period plus one cycle
// period late and never drifting (docs/can-protocol.md, HEARTBEAT).
// Verifies: REQ-CAN-008
TEST(Receiver, HeartbeatLateByAtMostOneCyclePeriod) {
  for (const std::int64_t period_us : {kCycleUs, std::int64_t{33333}, std::int64_t{20000}}) {
    const std::vector<Sent> sent = run_node(2000, period_us);
    std::vector<std::int64_t> times;
    for (const Sent& s : sent) {
      if (s.frame.id == heartbeat_id(kNode) && s.frame.data[0] != 0x00U) {
        times.push_back(s.t_us);
      }
    }
    const std::int64_t run_us = 1999 * period_us;
    ASSERT_EQ(times.size(), static_cast<std::size_t>(run_us / 100000)) << period_us;
    for (std::size_t k = 0; k < times.size(); ++k) {
      const std::int64_t due = static_cast<std::int64_t>(k + 1U) * 100000;
      EXPECT_GE(times[k], due) << k;
      EXPECT_LT(times[k], due + period_us) << k;  // late by less than one cycle period
      if (k > 0U) {
        const std::int64_t gap = times[k] - times[k - 1U];
        EXPECT_GT(gap, 100000 - period_us) << k;
        EXPECT_LT(gap, 100000 + period_us) << k;
      }
    }
  }
}

}  // namespace
}  // namespace can
}  // namespace tcpest
