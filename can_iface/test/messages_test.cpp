#include "tcpest/can_iface/messages.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "tcpest/test/mutate.hpp"

namespace tcpest {
namespace can {
namespace {

constexpr std::uint8_t kNode = kDefaultNodeId;

// Verifies: REQ-CAN-001
TEST(Messages, IdsFollowTheProtocolTable) {
  EXPECT_EQ(tcp_id(kNode), 0x190U);
  EXPECT_EQ(joints_id(kNode), 0x290U);
  EXPECT_EQ(mechanical_id(kNode), 0x390U);
  EXPECT_EQ(quality_id(kNode), 0x490U);
  EXPECT_EQ(heartbeat_id(kNode), 0x710U);
  EXPECT_EQ(emcy_id(kNode), 0x090U);
  EXPECT_EQ(encoder_prior_id(kNode), 0x210U);
}

// Verifies: REQ-CAN-002
TEST(Messages, TcpLayoutAndRoundTrip) {
  TcpMessage in;
  in.x_mm = -13.3;
  in.y_mm = 6.21;
  in.z_mm = 45.678;  // rounds to 45.68
  in.status = EstimateStatus::kDegraded;
  in.counter = 7;
  Frame frame;
  const auto result = encode_tcp(kNode, in, frame);
  ASSERT_TRUE(result.ok());
  EXPECT_EQ(result.value(), Saturation::kNone);
  EXPECT_EQ(frame.id, 0x190U);
  ASSERT_EQ(frame.length, 8U);
  // -1330 = 0xFACE little-endian; 621 = 0x026D; 4568 = 0x11D8.
  EXPECT_EQ(frame.data[0], 0xCE);
  EXPECT_EQ(frame.data[1], 0xFA);
  EXPECT_EQ(frame.data[2], 0x6D);
  EXPECT_EQ(frame.data[3], 0x02);
  EXPECT_EQ(frame.data[4], 0xD8);
  EXPECT_EQ(frame.data[5], 0x11);
  EXPECT_EQ(frame.data[6], 0x17);  // counter 7, status 1
  EXPECT_EQ(frame.data[7], 0xFA);  // the worked example of docs/can-protocol.md
  const auto out = decode_tcp(kNode, frame);
  ASSERT_TRUE(out.ok());
  EXPECT_NEAR(out.value().x_mm, -13.30, 1e-9);
  EXPECT_NEAR(out.value().y_mm, 6.21, 1e-9);
  EXPECT_NEAR(out.value().z_mm, 45.68, 1e-9);
  EXPECT_EQ(out.value().status, EstimateStatus::kDegraded);
  EXPECT_EQ(out.value().counter, 7U);
}

// Verifies: REQ-CAN-002
TEST(Messages, EncoderPriorWorkedExample) {
  // docs/can-protocol.md: lambda 15.5 mm, phi 0.125 rad, theta -0.25 rad, counter 0, valid.
  EncoderPriorMessage in{15.5, 0.125, -0.25, EstimateStatus::kValid, 0};
  Frame frame;
  ASSERT_TRUE(encode_encoder_prior(kNode, in, frame).ok());
  const std::uint8_t expected[8] = {0x0E, 0x06, 0xE2, 0x04, 0x3C, 0xF6, 0x00, 0xC6};
  EXPECT_EQ(frame.id, 0x210U);
  for (int i = 0; i < 8; ++i) {
    EXPECT_EQ(frame.data[i], expected[i]) << i;
  }
}

// Verifies: REQ-CAN-003
TEST(Messages, SaturationClampsAndForcesInvalidStatus) {
  TcpMessage in;
  in.x_mm = 400.0;    // > 327.67
  in.y_mm = -400.0;   // < -327.68
  in.z_mm = 327.67;   // exactly the maximum: fits
  in.status = EstimateStatus::kValid;
  Frame frame;
  const auto result = encode_tcp(kNode, in, frame);
  ASSERT_TRUE(result.ok());
  EXPECT_EQ(result.value(), Saturation::kSaturated);
  const auto out = decode_tcp(kNode, frame);
  ASSERT_TRUE(out.ok());
  EXPECT_NEAR(out.value().x_mm, 327.67, 1e-9);
  EXPECT_NEAR(out.value().y_mm, -327.68, 1e-9);
  EXPECT_NEAR(out.value().z_mm, 327.67, 1e-9);
  EXPECT_EQ(out.value().status, EstimateStatus::kInvalid);
}

// Verifies: REQ-CAN-003
TEST(Messages, NonFiniteValuesSaturateToZeroInvalid) {
  JointsMessage in;
  in.lambda_mm = std::numeric_limits<double>::quiet_NaN();
  in.phi_rad = std::numeric_limits<double>::infinity();
  in.theta_rad = 0.5;
  in.status = EstimateStatus::kValid;
  Frame frame;
  const auto result = encode_joints(kNode, in, frame);
  ASSERT_TRUE(result.ok());
  EXPECT_EQ(result.value(), Saturation::kSaturated);
  const auto out = decode_joints(kNode, frame);
  ASSERT_TRUE(out.ok());
  EXPECT_EQ(out.value().lambda_mm, 0.0);
  EXPECT_EQ(out.value().phi_rad, 0.0);
  EXPECT_NEAR(out.value().theta_rad, 0.5, 1e-9);
  EXPECT_EQ(out.value().status, EstimateStatus::kInvalid);
}

// Verifies: REQ-CAN-002
TEST(Messages, JointsAngleScale) {
  JointsMessage in;
  in.lambda_mm = 20.0;
  in.phi_rad = 3.14159;   // 31416 fits
  in.theta_rad = -3.2768;  // the minimum
  in.status = EstimateStatus::kHeld;
  in.counter = 14;
  Frame frame;
  ASSERT_TRUE(encode_joints(kNode, in, frame).ok());
  const auto out = decode_joints(kNode, frame);
  ASSERT_TRUE(out.ok());
  EXPECT_NEAR(out.value().phi_rad, 3.1416, 1e-9);
  EXPECT_NEAR(out.value().theta_rad, -3.2768, 1e-9);
  EXPECT_EQ(out.value().status, EstimateStatus::kHeld);
  EXPECT_EQ(out.value().counter, 14U);
}

// Verifies: REQ-CAN-001
TEST(Messages, RejectsBadArguments) {
  Frame frame;
  TcpMessage tcp;
  tcp.counter = 15;
  EXPECT_EQ(encode_tcp(kNode, tcp, frame).error(), CanError::kInvalidArgument);
  tcp.counter = 0;
  EXPECT_EQ(encode_tcp(0, tcp, frame).error(), CanError::kInvalidArgument);
  EXPECT_EQ(encode_tcp(128, tcp, frame).error(), CanError::kInvalidArgument);
  EXPECT_FALSE(encode_heartbeat(0, NmtState::kOperational, frame).ok());
  NmtMessage nmt;
  nmt.node_id = 200;
  EXPECT_FALSE(encode_nmt(nmt, frame).ok());
}

// Verifies: REQ-CAN-006
TEST(Messages, DecodersRejectWrongIdLengthCrcCounter) {
  TcpMessage tcp;
  Frame frame;
  ASSERT_TRUE(encode_tcp(kNode, tcp, frame).ok());
  EXPECT_EQ(decode_tcp(kNode + 1, frame).error(), CanError::kWrongId);
  Frame shorter = frame;
  shorter.length = 7;
  EXPECT_EQ(decode_tcp(kNode, shorter).error(), CanError::kWrongLength);
  Frame corrupt = frame;
  corrupt.data[2] ^= 0x01;
  EXPECT_EQ(decode_tcp(kNode, corrupt).error(), CanError::kBadCrc);
  Frame counter15 = frame;
  counter15.data[6] = 0x0F;
  counter15.data[7] = e2e_crc(counter15.id, counter15);
  EXPECT_EQ(decode_tcp(kNode, counter15).error(), CanError::kBadCounter);
}

// Random frames, most of them near a real one (its id, a byte or the
// length damaged, the CRC sometimes made right again), into every decoder:
// an error value or a message whose E2E bytes check, never a read past the
// frame (the sanitizer build runs this); a length beyond 8 is refused.
// Verifies: REQ-CAN-006
TEST(Messages, RandomFramesAreRefusedOrCheckOut) {
  test::Mutator random(17U);
  Frame valid[3];
  ASSERT_TRUE(encode_tcp(kNode, TcpMessage{}, valid[0]).ok());
  ASSERT_TRUE(encode_encoder_prior(kNode, EncoderPriorMessage{}, valid[1]).ok());
  ASSERT_TRUE(encode_heartbeat(kNode, NmtState::kOperational, valid[2]).ok());
  int accepted = 0;
  for (int i = 0; i < 100000; ++i) {
    Frame frame = valid[random.below(3U)];
    switch (random.below(4U)) {
      case 0U:
        frame.id = static_cast<std::uint32_t>(random.below(0x800U));
        break;
      case 1U:
        frame.length = static_cast<std::uint8_t>(random.below(256U));
        break;
      case 2U:
        frame.data[random.below(kMaxDataLength)] = static_cast<std::uint8_t>(random.below(256U));
        break;
      default:
        frame.data[random.below(7U)] = static_cast<std::uint8_t>(random.below(256U));
        frame.data[7] = e2e_crc(frame.id, frame);  // a sender's bug, not line noise
        break;
    }
    const bool e2e_ok = frame.length == kMaxDataLength && frame.data[7] == e2e_crc(frame.id, frame) &&
                        (frame.data[6] & 0x0FU) != 0x0FU;
    const auto tcp = decode_tcp(kNode, frame);
    const auto joints = decode_joints(kNode, frame);
    const auto prior = decode_encoder_prior(kNode, frame);
    const auto mechanical = decode_mechanical(kNode, frame);
    const auto quality = decode_quality(kNode, frame);
    const auto heartbeat = decode_heartbeat(kNode, frame);
    const auto emcy = decode_emcy(kNode, frame);
    const auto nmt = decode_nmt(frame);
    const auto sync = decode_sync(frame);
    for (const bool protected_ok : {tcp.ok(), joints.ok(), prior.ok()}) {
      EXPECT_TRUE(!protected_ok || e2e_ok) << i;
    }
    if (prior.ok()) {
      EXPECT_TRUE(std::isfinite(prior.value().lambda_mm) && std::isfinite(prior.value().phi_rad) &&
                  std::isfinite(prior.value().theta_rad));
      ++accepted;
    }
    for (const bool any_ok : {tcp.ok(), joints.ok(), prior.ok(), mechanical.ok(), quality.ok(), heartbeat.ok(),
                              emcy.ok(), nmt.ok(), sync.ok()}) {
      EXPECT_TRUE(!any_ok || frame.length <= kMaxDataLength) << i;
    }
  }
  EXPECT_GT(accepted, 1000);  // the re-protected damage still reaches the decoder's values
}

// Verifies: REQ-CAN-006
TEST(Messages, UndefinedStatusNibbleReadsAsInvalid) {
  TcpMessage tcp;
  Frame frame;
  ASSERT_TRUE(encode_tcp(kNode, tcp, frame).ok());
  frame.data[6] = 0x93;  // status 9, counter 3
  frame.data[7] = e2e_crc(frame.id, frame);
  const auto out = decode_tcp(kNode, frame);
  ASSERT_TRUE(out.ok());
  EXPECT_EQ(out.value().status, EstimateStatus::kInvalid);
}

// Verifies: REQ-CAN-002, REQ-CAN-003
TEST(Messages, MechanicalRoundTripAndSaturation) {
  MechanicalMessage in;
  in.x_ch_mm = 1.23;
  in.y_ch_mm = -0.45;
  in.psi_rad = 0.1745;
  in.mu_rad = -0.002;
  Frame frame;
  auto result = encode_mechanical(kNode, in, frame);
  ASSERT_TRUE(result.ok());
  EXPECT_EQ(result.value(), Saturation::kNone);
  auto out = decode_mechanical(kNode, frame);
  ASSERT_TRUE(out.ok());
  EXPECT_NEAR(out.value().x_ch_mm, 1.23, 1e-9);
  EXPECT_NEAR(out.value().y_ch_mm, -0.45, 1e-9);
  EXPECT_NEAR(out.value().psi_rad, 0.1745, 1e-9);
  EXPECT_NEAR(out.value().mu_rad, -0.002, 1e-9);
  in.mu_rad = 10.0;
  result = encode_mechanical(kNode, in, frame);
  ASSERT_TRUE(result.ok());
  EXPECT_EQ(result.value(), Saturation::kSaturated);
  out = decode_mechanical(kNode, frame);
  EXPECT_NEAR(out.value().mu_rad, 3.2767, 1e-9);
}

// Verifies: REQ-CAN-002, REQ-CAN-003
TEST(Messages, QualityRoundTripAndSaturation) {
  QualityMessage in;
  in.corners_detected = 12;
  in.corners_used = 10;
  in.rms_px = 0.87;
  in.latency_us = 12345;
  in.frame_counter = 65535;
  Frame frame;
  auto result = encode_quality(kNode, in, frame);
  ASSERT_TRUE(result.ok());
  EXPECT_EQ(result.value(), Saturation::kNone);
  auto out = decode_quality(kNode, frame);
  ASSERT_TRUE(out.ok());
  EXPECT_EQ(out.value().corners_detected, 12U);
  EXPECT_EQ(out.value().corners_used, 10U);
  EXPECT_NEAR(out.value().rms_px, 0.87, 1e-9);
  EXPECT_EQ(out.value().latency_us, 12345);
  EXPECT_EQ(out.value().frame_counter, 65535U);
  in.latency_us = 1000000;
  in.rms_px = std::numeric_limits<double>::quiet_NaN();
  result = encode_quality(kNode, in, frame);
  EXPECT_EQ(result.value(), Saturation::kSaturated);
  out = decode_quality(kNode, frame);
  EXPECT_EQ(out.value().latency_us, 65535);
  EXPECT_NEAR(out.value().rms_px, 655.35, 1e-9);
  in.latency_us = -5;
  in.rms_px = -1.0;
  result = encode_quality(kNode, in, frame);
  EXPECT_EQ(result.value(), Saturation::kSaturated);
  out = decode_quality(kNode, frame);
  EXPECT_EQ(out.value().latency_us, 0);
  EXPECT_EQ(out.value().rms_px, 0.0);
}

// Verifies: REQ-CAN-002, REQ-CAN-012
TEST(Messages, HeartbeatEmcyNmtSync) {
  Frame frame;
  ASSERT_TRUE(encode_heartbeat(kNode, NmtState::kPreOperational, frame).ok());
  EXPECT_EQ(frame.id, 0x710U);
  EXPECT_EQ(frame.length, 1U);
  EXPECT_EQ(frame.data[0], 0x7F);
  EXPECT_EQ(decode_heartbeat(kNode, frame).value(), NmtState::kPreOperational);
  frame.data[0] = 0x42;
  EXPECT_FALSE(decode_heartbeat(kNode, frame).ok());

  EmcyMessage emcy;
  emcy.error_code = 0x8250;
  emcy.error_register = 0x11;
  emcy.fault_id = 7;
  emcy.detail = 0xA1B2C3D4;
  ASSERT_TRUE(encode_emcy(kNode, emcy, frame).ok());
  EXPECT_EQ(frame.id, 0x090U);
  EXPECT_EQ(frame.data[0], 0x50);
  EXPECT_EQ(frame.data[1], 0x82);
  EXPECT_EQ(frame.data[4], 0xD4);
  EXPECT_EQ(frame.data[7], 0xA1);
  const auto back = decode_emcy(kNode, frame);
  ASSERT_TRUE(back.ok());
  EXPECT_EQ(back.value().error_code, 0x8250U);
  EXPECT_EQ(back.value().error_register, 0x11U);
  EXPECT_EQ(back.value().fault_id, 7U);
  EXPECT_EQ(back.value().detail, 0xA1B2C3D4U);

  NmtMessage nmt;
  nmt.command = NmtCommand::kResetCommunication;
  nmt.node_id = kNode;
  ASSERT_TRUE(encode_nmt(nmt, frame).ok());
  EXPECT_EQ(frame.id, 0U);
  EXPECT_EQ(frame.data[0], 0x82);
  EXPECT_EQ(decode_nmt(frame).value().command, NmtCommand::kResetCommunication);
  frame.data[0] = 0x03;
  EXPECT_EQ(decode_nmt(frame).error(), CanError::kUnknownCommand);
  frame.length = 1;
  EXPECT_EQ(decode_nmt(frame).error(), CanError::kWrongLength);

  ASSERT_TRUE(encode_sync(frame).ok());
  EXPECT_TRUE(decode_sync(frame).ok());
  frame.length = 1;  // optional SYNC counter
  EXPECT_TRUE(decode_sync(frame).ok());
  frame.length = 2;
  EXPECT_EQ(decode_sync(frame).error(), CanError::kWrongLength);
}

// Verifies: REQ-ERR-008
TEST(Messages, EveryErrorHasAName) {
  for (int e = 0; e <= static_cast<int>(CanError::kFull); ++e) {
    EXPECT_STRNE(to_string(static_cast<CanError>(e)), "unknown error");
  }
}

}  // namespace
}  // namespace can
}  // namespace tcpest
