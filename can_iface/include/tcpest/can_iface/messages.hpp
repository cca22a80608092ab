// Encoders and decoders for every message of docs/can-protocol.md: physical
// values (mm, rad, px, us) in, CAN frames out, and back. Pure functions: no
// state, no heap, no clock. Counters and receive-side checks live in e2e.hpp,
// the node's behaviour in node.hpp.
#pragma once

#include <cstdint>

#include "tcpest/can_iface/error.hpp"
#include "tcpest/can_iface/frame.hpp"
#include "tcpest/common/result.hpp"

namespace tcpest {
namespace can {

// ---- Identifiers ---------------------------------------------------------
constexpr std::uint8_t kDefaultNodeId = 0x10U;
constexpr std::uint8_t kMinNodeId = 1U;    // CiA 301 node IDs are 1..127
constexpr std::uint8_t kMaxNodeId = 127U;
inline bool valid_node_id(std::uint8_t node_id) noexcept { return node_id >= kMinNodeId && node_id <= kMaxNodeId; }

constexpr std::uint32_t kNmtId = 0x000U;
constexpr std::uint32_t kSyncId = 0x080U;
constexpr std::uint32_t kEmcyBase = 0x080U;
constexpr std::uint32_t kTcpBase = 0x180U;
constexpr std::uint32_t kEncoderPriorBase = 0x200U;
constexpr std::uint32_t kJointsBase = 0x280U;
constexpr std::uint32_t kMechanicalBase = 0x380U;
constexpr std::uint32_t kQualityBase = 0x480U;
constexpr std::uint32_t kHeartbeatBase = 0x700U;

inline std::uint32_t tcp_id(std::uint8_t node_id) noexcept { return kTcpBase + node_id; }
inline std::uint32_t joints_id(std::uint8_t node_id) noexcept { return kJointsBase + node_id; }
inline std::uint32_t mechanical_id(std::uint8_t node_id) noexcept { return kMechanicalBase + node_id; }
inline std::uint32_t quality_id(std::uint8_t node_id) noexcept { return kQualityBase + node_id; }
inline std::uint32_t heartbeat_id(std::uint8_t node_id) noexcept { return kHeartbeatBase + node_id; }
inline std::uint32_t emcy_id(std::uint8_t node_id) noexcept { return kEmcyBase + node_id; }
inline std::uint32_t encoder_prior_id(std::uint8_t node_id) noexcept { return kEncoderPriorBase + node_id; }

// ---- Lengths -------------------------------------------------------------
constexpr std::uint8_t kPdoLength = 8U;
constexpr std::uint8_t kHeartbeatLength = 1U;
constexpr std::uint8_t kEmcyLength = 8U;
constexpr std::uint8_t kNmtLength = 2U;

// ---- Scales (one LSB) ----------------------------------------------------
constexpr double kLengthLsbMm = 0.01;
constexpr double kAngleLsbRad = 0.0001;
constexpr double kRmsLsbPx = 0.01;

// ---- Status nibble and alive counter (byte 6 of E2E messages) -------------
enum class EstimateStatus : std::uint8_t {
  kValid = 0U,     // estimate from this frame
  kDegraded = 1U,  // estimate from this frame, too few corners or large residual
  kHeld = 2U,      // no estimate this frame: the last one is repeated
  kInvalid = 3U,   // no estimate yet, a fault, or a saturated value
};
const char* to_string(EstimateStatus status) noexcept;
constexpr std::uint8_t kMaxAliveCounter = 14U;  // 0..14; 15 is never sent

// ---- Messages in physical units ------------------------------------------
struct TcpMessage {
  double x_mm = 0.0;
  double y_mm = 0.0;
  double z_mm = 0.0;
  EstimateStatus status = EstimateStatus::kInvalid;
  std::uint8_t counter = 0U;
};

struct JointsMessage {
  double lambda_mm = 0.0;
  double phi_rad = 0.0;
  double theta_rad = 0.0;
  EstimateStatus status = EstimateStatus::kInvalid;
  std::uint8_t counter = 0U;
};

// Same layout as JOINTS, sent by the robot (received by the estimator).
using EncoderPriorMessage = JointsMessage;

struct MechanicalMessage {
  double x_ch_mm = 0.0;
  double y_ch_mm = 0.0;
  double psi_rad = 0.0;
  double mu_rad = 0.0;
};

struct QualityMessage {
  std::uint8_t corners_detected = 0U;
  std::uint8_t corners_used = 0U;
  double rms_px = 0.0;
  std::int64_t latency_us = 0;  // saturates to 0..65535 on the wire
  std::uint16_t frame_counter = 0U;
};

enum class NmtState : std::uint8_t {
  kBootUp = 0x00U,
  kStopped = 0x04U,
  kOperational = 0x05U,
  kPreOperational = 0x7FU,
};
const char* to_string(NmtState state) noexcept;

enum class NmtCommand : std::uint8_t {
  kStart = 0x01U,
  kStop = 0x02U,
  kEnterPreOperational = 0x80U,
  kResetNode = 0x81U,
  kResetCommunication = 0x82U,
};

struct NmtMessage {
  NmtCommand command = NmtCommand::kStart;
  std::uint8_t node_id = 0U;  // 0: all nodes
};

struct EmcyMessage {
  std::uint16_t error_code = 0U;     // CiA 301 code; 0x0000: error reset
  std::uint8_t error_register = 0U;  // CiA 301 object 0x1001
  std::uint8_t fault_id = 0U;        // byte 3: which fault (emcy.hpp)
  std::uint32_t detail = 0U;         // bytes 4-7: the fault's detail
};

// kSaturated: a value did not fit its field; it was clamped and, where the
// message has a status nibble, the status was forced to kInvalid.
enum class Saturation : std::uint8_t { kNone, kSaturated };

// ---- Encoders (node_id 1..127, counter 0..14, else kInvalidArgument) ------
Result<Saturation, CanError> encode_tcp(std::uint8_t node_id, const TcpMessage& message, Frame& out) noexcept;
Result<Saturation, CanError> encode_joints(std::uint8_t node_id, const JointsMessage& message, Frame& out) noexcept;
Result<Saturation, CanError> encode_encoder_prior(std::uint8_t node_id, const EncoderPriorMessage& message,
                                                  Frame& out) noexcept;
Result<Saturation, CanError> encode_mechanical(std::uint8_t node_id, const MechanicalMessage& message,
                                               Frame& out) noexcept;
Result<Saturation, CanError> encode_quality(std::uint8_t node_id, const QualityMessage& message, Frame& out) noexcept;
Status<CanError> encode_heartbeat(std::uint8_t node_id, NmtState state, Frame& out) noexcept;
Status<CanError> encode_emcy(std::uint8_t node_id, const EmcyMessage& message, Frame& out) noexcept;
Status<CanError> encode_nmt(const NmtMessage& message, Frame& out) noexcept;
Status<CanError> encode_sync(Frame& out) noexcept;

// ---- Decoders --------------------------------------------------------------
// E2E messages: kWrongId, kWrongLength, kBadCrc, kBadCounter (counter 15).
// Counter sequence and age are the receiver's business (e2e.hpp).
Result<TcpMessage, CanError> decode_tcp(std::uint8_t node_id, const Frame& frame) noexcept;
Result<JointsMessage, CanError> decode_joints(std::uint8_t node_id, const Frame& frame) noexcept;
Result<EncoderPriorMessage, CanError> decode_encoder_prior(std::uint8_t node_id, const Frame& frame) noexcept;
Result<MechanicalMessage, CanError> decode_mechanical(std::uint8_t node_id, const Frame& frame) noexcept;
Result<QualityMessage, CanError> decode_quality(std::uint8_t node_id, const Frame& frame) noexcept;
Result<NmtState, CanError> decode_heartbeat(std::uint8_t node_id, const Frame& frame) noexcept;
Result<EmcyMessage, CanError> decode_emcy(std::uint8_t node_id, const Frame& frame) noexcept;
// NMT: kWrongLength, kUnknownCommand. The node ID is returned, not checked.
Result<NmtMessage, CanError> decode_nmt(const Frame& frame) noexcept;
// SYNC: 0 bytes, or 1 (CiA 301 optional SYNC counter, ignored).
Status<CanError> decode_sync(const Frame& frame) noexcept;

// ---- E2E helpers (byte 6: counter | status << 4; byte 7: CRC) --------------
// CRC over the COB-ID (two bytes, low first) and payload bytes 0..6.
std::uint8_t e2e_crc(std::uint32_t cob_id, const Frame& frame) noexcept;
// Writes byte 6 and the CRC into an 8-byte frame whose bytes 0..5 are set.
Status<CanError> e2e_protect(std::uint8_t counter, EstimateStatus status, Frame& frame) noexcept;

}  // namespace can
}  // namespace tcpest
