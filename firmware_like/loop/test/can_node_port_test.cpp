// The loop's port to the CAN node (can_node_port) on the simulated bus: the
// robot's NMT commands and encoder priors as the loop reads them, what it
// may send in each state, and a bus-off as the loop lives through it.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <memory>

#include "tcpest/can_iface/messages.hpp"
#include "tcpest/hal/camera/file_sources.hpp"
#include "tcpest/hal/can/sim_bus.hpp"
#include "tcpest/loop/can_node_port.hpp"
#include "tcpest/loop/executive.hpp"
#include "tcpest/loop/motion.hpp"
#include "oracle_pipeline.hpp"

namespace tcpest {
namespace loop {
namespace {

constexpr std::uint8_t kNodeId = 0x10U;

// The port on endpoint 0 of a simulated bus; the robot on endpoint 1. The
// node waits for the robot's NMT start (can.start_operational off, the default).
struct PortRig {
  hal::SimulatedClock clock{5 * hal::kNsPerS};
  hal::SimBus bus;
  LoopConfig config;
  CanNodePort port{clock, bus.endpoint(0), &bus, nullptr, "sim0"};
  PortRig() {
    config.can.start_operational = false;
    EXPECT_TRUE(port.configure(node_config(config)).ok());
  }
  void robot_sends_nmt(can::NmtCommand command) {
    can::Frame f;
    ASSERT_TRUE(can::encode_nmt(can::NmtMessage{command, kNodeId}, f).ok());
    ASSERT_TRUE(bus.endpoint(1).send(f).ok());
  }
  void robot_sends_prior(double lambda_mm, double phi_rad, double theta_rad, std::uint8_t counter) {
    can::EncoderPriorMessage m;
    m.lambda_mm = lambda_mm;
    m.phi_rad = phi_rad;
    m.theta_rad = theta_rad;
    m.status = can::EstimateStatus::kValid;
    m.counter = counter;
    can::Frame f;
    ASSERT_TRUE(can::encode_encoder_prior(kNodeId, m, f).ok());
    ASSERT_TRUE(bus.endpoint(1).send(f).ok());
  }
  // Reads, as the loop does at the start of a cycle, `ms` later.
  Status<PortError> step(int ms) {
    clock.advance_ns(static_cast<std::int64_t>(ms) * hal::kNsPerMs);
    return port.receive(clock.now_ns());
  }
};

// Verifies: REQ-LOOP-007
TEST(CanNodePort, TheRobotsNmtCommandsSetTheModeAndAResetIsTakenOnce) {
  PortRig rig;
  ASSERT_EQ(rig.config.can.node_id, kNodeId);
  ASSERT_TRUE(rig.step(1).ok());
  EXPECT_NE(rig.port.mode(), NodeMode::kOperational);  // not before the robot says so
  rig.robot_sends_nmt(can::NmtCommand::kStart);
  ASSERT_TRUE(rig.step(1).ok());
  EXPECT_EQ(rig.port.mode(), NodeMode::kOperational);
  rig.robot_sends_nmt(can::NmtCommand::kStop);
  ASSERT_TRUE(rig.step(1).ok());
  EXPECT_EQ(rig.port.mode(), NodeMode::kStopped);
  rig.robot_sends_nmt(can::NmtCommand::kEnterPreOperational);
  ASSERT_TRUE(rig.step(1).ok());
  EXPECT_EQ(rig.port.mode(), NodeMode::kPreOperational);
  EXPECT_FALSE(rig.port.take_reset());
  rig.robot_sends_nmt(can::NmtCommand::kResetNode);
  ASSERT_TRUE(rig.step(1).ok());
  EXPECT_TRUE(rig.port.take_reset());
  EXPECT_FALSE(rig.port.take_reset());  // taken once
}

// Verifies: REQ-LOOP-007
TEST(CanNodePort, AnEstimateIsRefusedUnlessOperational) {
  PortRig rig;
  ASSERT_TRUE(rig.step(1).ok());
  Publication p{};
  p.status = EstimateStatus::kValid;
  std::int64_t latency_ns = -1;
  const auto before = rig.port.publish(p, latency_ns);
  ASSERT_FALSE(before.ok());
  EXPECT_EQ(before.error(), PortError::kNotAllowed);
  rig.robot_sends_nmt(can::NmtCommand::kStart);
  ASSERT_TRUE(rig.step(1).ok());
  p.frame_timestamp_ns = rig.clock.now_ns();
  rig.clock.advance_ns(3 * hal::kNsPerMs);
  EXPECT_TRUE(rig.port.publish(p, latency_ns).ok());
  EXPECT_EQ(latency_ns, 3 * hal::kNsPerMs);
}

// Verifies: REQ-LOOP-012
TEST(CanNodePort, TheRobotsEncoderPriorIsReadBackWhileFresh) {
  PortRig rig;
  ASSERT_TRUE(rig.step(1).ok());  // boot-up (a command during boot-up is ignored)
  rig.robot_sends_nmt(can::NmtCommand::kStart);
  ASSERT_TRUE(rig.step(1).ok());
  JointPrior prior{};
  EXPECT_FALSE(rig.port.encoder_prior(rig.clock.now_ns(), prior));  // none yet
  rig.robot_sends_prior(23.4, 0.5, -0.8, 0U);
  ASSERT_TRUE(rig.step(1).ok());
  ASSERT_TRUE(rig.port.encoder_prior(rig.clock.now_ns(), prior));
  EXPECT_NEAR(prior.lambda_mm, 23.4, 0.01);
  EXPECT_NEAR(prior.phi_rad, 0.5, 0.001);
  EXPECT_NEAR(prior.theta_rad, -0.8, 0.001);
  rig.clock.advance_ns(10 * hal::kNsPerS);
  EXPECT_FALSE(rig.port.encoder_prior(rig.clock.now_ns(), prior));  // stale
}

// A bus-off lasting 3 s: the loop counts one loss, keeps processing, does
// not call the bus back while the controller still reports bus-off, and
// recovers once it is over.
// Verifies: REQ-LOOP-009
TEST(CanNodePort, ABusOffIsOneLossAndTheLoopRecoversWhenItEnds) {
  const auto camera = solver::CameraModel::create(solver::default_pal_camera());
  const auto model = solver::InstrumentModel::create(solver::InstrumentGeometry{});
  ASSERT_TRUE(camera.ok() && model.ok());
  MotionSequence motion;
  motion.frames = 250U;
  ModelScene scene(camera.value(), model.value(), motion);
  hal::SimCamera source(scene, 25.0, false);
  OraclePipeline pipeline(camera.value(), model.value());
  pipeline.set_truth_source(&source);
  PortRig rig;
  LoopParts parts{&source, &rig.clock, &pipeline, &rig.port, &camera.value(), &model.value()};
  auto created = Executive::create(rig.config, parts);
  ASSERT_TRUE(created.ok());
  Executive& loop = *created.value();
  loop.start();
  std::array<hal::ReceivedFrame, 64> rx{};
  const auto run = [&](int cycles) {
    for (int i = 0; i < cycles; ++i) {
      ASSERT_EQ(loop.run_cycle(), CycleOutcome::kContinue);
      static_cast<void>(rig.bus.endpoint(1).receive(rx.data(), rx.size()));  // the robot reads
    }
  };
  run(1);  // boot-up
  rig.robot_sends_nmt(can::NmtCommand::kStart);
  run(9);
  ASSERT_EQ(loop.stats().published, 9U) << rig.port.node().counters().rx_ignored_in_state;
  rig.bus.set_bus_off(true);
  run(75);  // 3 s at 25 Hz; the retry period is 1 s
  EXPECT_TRUE(loop.last().bus_lost);
  EXPECT_EQ(loop.stats().bus_lost_events, 1U);
  EXPECT_EQ(loop.stats().bus_recoveries, 0U);
  EXPECT_EQ(loop.stats().frames, 85U);  // processing went on
  rig.bus.set_bus_off(false);
  run(50);
  EXPECT_FALSE(loop.last().bus_lost);
  EXPECT_EQ(loop.stats().bus_lost_events, 1U);
  EXPECT_EQ(loop.stats().bus_recoveries, 1U);
}

}  // namespace
}  // namespace loop
}  // namespace tcpest
