#include "tcpest/can_iface/messages.hpp"

#include <cmath>
#include <limits>

#include "tcpest/can_iface/crc8.hpp"

namespace tcpest {
namespace can {
namespace {

constexpr std::uint8_t kStatusShift = 4U;
constexpr std::uint8_t kNibbleMask = 0x0FU;
constexpr std::uint8_t kStatusMask = 0x03U;  // statuses 4..15 are not defined
constexpr std::size_t kE2eByte = 6U;
constexpr std::size_t kCrcByte = 7U;

struct Scaled16 {
  std::int16_t raw = 0;
  bool saturated = false;
};

// value / lsb rounded to nearest; out of int16 range or not finite: clamped
// (non-finite to 0) and flagged.
Scaled16 scale_signed(double value, double lsb) noexcept {
  Scaled16 out;
  if (!std::isfinite(value)) {
    out.saturated = true;
    return out;
  }
  const double scaled = std::nearbyint(value / lsb);
  constexpr double kMin = std::numeric_limits<std::int16_t>::min();
  constexpr double kMax = std::numeric_limits<std::int16_t>::max();
  if (scaled < kMin) {
    out.raw = std::numeric_limits<std::int16_t>::min();
    out.saturated = true;
  } else if (scaled > kMax) {
    out.raw = std::numeric_limits<std::int16_t>::max();
    out.saturated = true;
  } else {
    out.raw = static_cast<std::int16_t>(scaled);
  }
  return out;
}

struct ScaledU16 {
  std::uint16_t raw = 0U;
  bool saturated = false;
};

ScaledU16 scale_unsigned(double value, double lsb) noexcept {
  ScaledU16 out;
  constexpr double kMax = std::numeric_limits<std::uint16_t>::max();
  if (std::isnan(value)) {
    out.raw = std::numeric_limits<std::uint16_t>::max();
    out.saturated = true;
    return out;
  }
  const double scaled = std::nearbyint(value / lsb);
  if (scaled < 0.0) {
    out.saturated = true;
  } else if (scaled > kMax) {
    out.raw = std::numeric_limits<std::uint16_t>::max();
    out.saturated = true;
  } else {
    out.raw = static_cast<std::uint16_t>(scaled);
  }
  return out;
}

void put_u16(Frame& frame, std::size_t at, std::uint16_t value) noexcept {
  frame.data[at] = static_cast<std::uint8_t>(value & 0xFFU);
  frame.data[at + 1U] = static_cast<std::uint8_t>(value >> 8U);
}
void put_i16(Frame& frame, std::size_t at, std::int16_t value) noexcept {
  put_u16(frame, at, static_cast<std::uint16_t>(value));
}
std::uint16_t get_u16(const Frame& frame, std::size_t at) noexcept {
  return static_cast<std::uint16_t>(frame.data[at] | (frame.data[at + 1U] << 8U));
}
std::int16_t get_i16(const Frame& frame, std::size_t at) noexcept {
  // Two's complement reinterpretation, well defined since C++20 and on every
  // compiler we build with.
  return static_cast<std::int16_t>(get_u16(frame, at));
}

void start_frame(Frame& frame, std::uint32_t id, std::uint8_t length) noexcept {
  frame = Frame{};
  frame.id = id;
  frame.length = length;
}

Result<Saturation, CanError> encode_three(std::uint8_t node_id, std::uint32_t id, double a, double a_lsb, double b,
                                          double b_lsb, double c, double c_lsb, EstimateStatus status,
                                          std::uint8_t counter, Frame& out) noexcept {
  using R = Result<Saturation, CanError>;
  if (!valid_node_id(node_id) || counter > kMaxAliveCounter ||
      static_cast<std::uint8_t>(status) > static_cast<std::uint8_t>(EstimateStatus::kInvalid)) {
    return R::failure(CanError::kInvalidArgument);
  }
  const Scaled16 sa = scale_signed(a, a_lsb);
  const Scaled16 sb = scale_signed(b, b_lsb);
  const Scaled16 sc = scale_signed(c, c_lsb);
  const bool saturated = sa.saturated || sb.saturated || sc.saturated;
  start_frame(out, id, kPdoLength);
  put_i16(out, 0U, sa.raw);
  put_i16(out, 2U, sb.raw);
  put_i16(out, 4U, sc.raw);
  const EstimateStatus sent = saturated ? EstimateStatus::kInvalid : status;
  if (!e2e_protect(counter, sent, out)) {
    return R::failure(CanError::kInvalidArgument);
  }
  return R::success(saturated ? Saturation::kSaturated : Saturation::kNone);
}

struct Three {
  double a = 0.0;
  double b = 0.0;
  double c = 0.0;
  EstimateStatus status = EstimateStatus::kInvalid;
  std::uint8_t counter = 0U;
};

Result<Three, CanError> decode_three(std::uint32_t id, const Frame& frame, double a_lsb, double b_lsb,
                                     double c_lsb) noexcept {
  using R = Result<Three, CanError>;
  if (frame.id != id) {
    return R::failure(CanError::kWrongId);
  }
  if (frame.length != kPdoLength) {
    return R::failure(CanError::kWrongLength);
  }
  if (e2e_crc(id, frame) != frame.data[kCrcByte]) {
    return R::failure(CanError::kBadCrc);
  }
  Three out;
  out.counter = static_cast<std::uint8_t>(frame.data[kE2eByte] & kNibbleMask);
  if (out.counter > kMaxAliveCounter) {
    return R::failure(CanError::kBadCounter);
  }
  const auto status_nibble = static_cast<std::uint8_t>(frame.data[kE2eByte] >> kStatusShift);
  // Status values above 3 are not defined: read as invalid.
  out.status = status_nibble > kStatusMask ? EstimateStatus::kInvalid : static_cast<EstimateStatus>(status_nibble);
  out.a = get_i16(frame, 0U) * a_lsb;
  out.b = get_i16(frame, 2U) * b_lsb;
  out.c = get_i16(frame, 4U) * c_lsb;
  return R::success(out);
}

bool check_id_length(const Frame& frame, std::uint32_t id, std::uint8_t length, CanError& error) noexcept {
  if (frame.id != id) {
    error = CanError::kWrongId;
    return false;
  }
  if (frame.length != length) {
    error = CanError::kWrongLength;
    return false;
  }
  return true;
}

}  // namespace

const char* to_string(CanError error) noexcept {
  switch (error) {
    case CanError::kInvalidArgument: return "invalid argument";
    case CanError::kWrongId: return "wrong COB-ID";
    case CanError::kUnknownId: return "unknown COB-ID";
    case CanError::kWrongLength: return "wrong length";
    case CanError::kBadCrc: return "bad CRC";
    case CanError::kBadCounter: return "bad alive counter (15)";
    case CanError::kCounterRepeated: return "alive counter repeated";
    case CanError::kCounterJump: return "alive counter jumped";
    case CanError::kInvalidStatus: return "sender status invalid";
    case CanError::kStale: return "stale (timeout)";
    case CanError::kNoData: return "no data";
    case CanError::kUnknownCommand: return "unknown NMT command";
    case CanError::kOtherNode: return "NMT for another node";
    case CanError::kNotAllowed: return "not allowed in this NMT state";
    case CanError::kFull: return "output full";
  }
  return "unknown error";
}

const char* to_string(EstimateStatus status) noexcept {
  switch (status) {
    case EstimateStatus::kValid: return "valid";
    case EstimateStatus::kDegraded: return "degraded";
    case EstimateStatus::kHeld: return "held";
    case EstimateStatus::kInvalid: return "invalid";
  }
  return "unknown";
}

const char* to_string(NmtState state) noexcept {
  switch (state) {
    case NmtState::kBootUp: return "boot-up";
    case NmtState::kStopped: return "stopped";
    case NmtState::kOperational: return "operational";
    case NmtState::kPreOperational: return "pre-operational";
  }
  return "unknown";
}

std::uint8_t e2e_crc(std::uint32_t cob_id, const Frame& frame) noexcept {
  const std::uint8_t id_bytes[2] = {static_cast<std::uint8_t>(cob_id & 0xFFU),
                                    static_cast<std::uint8_t>((cob_id >> 8U) & 0xFFU)};
  std::uint8_t crc = crc8_update(kCrc8Init, id_bytes, sizeof id_bytes);
  crc = crc8_update(crc, frame.data.data(), kCrcByte);
  return crc8_finish(crc);
}

Status<CanError> e2e_protect(std::uint8_t counter, EstimateStatus status, Frame& frame) noexcept {
  if (counter > kMaxAliveCounter || frame.length != kPdoLength) {
    return Status<CanError>::failure(CanError::kInvalidArgument);
  }
  frame.data[kE2eByte] = static_cast<std::uint8_t>(counter | (static_cast<std::uint8_t>(status) << kStatusShift));
  frame.data[kCrcByte] = e2e_crc(frame.id, frame);
  return ok_status<CanError>();
}

Result<Saturation, CanError> encode_tcp(std::uint8_t node_id, const TcpMessage& message, Frame& out) noexcept {
  return encode_three(node_id, tcp_id(node_id), message.x_mm, kLengthLsbMm, message.y_mm, kLengthLsbMm,
                      message.z_mm, kLengthLsbMm, message.status, message.counter, out);
}

Result<Saturation, CanError> encode_joints(std::uint8_t node_id, const JointsMessage& message, Frame& out) noexcept {
  return encode_three(node_id, joints_id(node_id), message.lambda_mm, kLengthLsbMm, message.phi_rad, kAngleLsbRad,
                      message.theta_rad, kAngleLsbRad, message.status, message.counter, out);
}

Result<Saturation, CanError> encode_encoder_prior(std::uint8_t node_id, const EncoderPriorMessage& message,
                                                  Frame& out) noexcept {
  return encode_three(node_id, encoder_prior_id(node_id), message.lambda_mm, kLengthLsbMm, message.phi_rad,
                      kAngleLsbRad, message.theta_rad, kAngleLsbRad, message.status, message.counter, out);
}

Result<Saturation, CanError> encode_mechanical(std::uint8_t node_id, const MechanicalMessage& message,
                                               Frame& out) noexcept {
  using R = Result<Saturation, CanError>;
  if (!valid_node_id(node_id)) {
    return R::failure(CanError::kInvalidArgument);
  }
  const Scaled16 x = scale_signed(message.x_ch_mm, kLengthLsbMm);
  const Scaled16 y = scale_signed(message.y_ch_mm, kLengthLsbMm);
  const Scaled16 psi = scale_signed(message.psi_rad, kAngleLsbRad);
  const Scaled16 mu = scale_signed(message.mu_rad, kAngleLsbRad);
  start_frame(out, mechanical_id(node_id), kPdoLength);
  put_i16(out, 0U, x.raw);
  put_i16(out, 2U, y.raw);
  put_i16(out, 4U, psi.raw);
  put_i16(out, 6U, mu.raw);
  const bool saturated = x.saturated || y.saturated || psi.saturated || mu.saturated;
  return R::success(saturated ? Saturation::kSaturated : Saturation::kNone);
}

Result<Saturation, CanError> encode_quality(std::uint8_t node_id, const QualityMessage& message, Frame& out) noexcept {
  using R = Result<Saturation, CanError>;
  if (!valid_node_id(node_id)) {
    return R::failure(CanError::kInvalidArgument);
  }
  const ScaledU16 rms = scale_unsigned(message.rms_px, kRmsLsbPx);
  constexpr std::int64_t kMaxLatency = std::numeric_limits<std::uint16_t>::max();
  bool latency_saturated = true;
  std::uint16_t latency = 0U;
  if (message.latency_us > kMaxLatency) {
    latency = std::numeric_limits<std::uint16_t>::max();
  } else if (message.latency_us >= 0) {
    latency = static_cast<std::uint16_t>(message.latency_us);
    latency_saturated = false;
  }
  start_frame(out, quality_id(node_id), kPdoLength);
  out.data[0] = message.corners_detected;
  out.data[1] = message.corners_used;
  put_u16(out, 2U, rms.raw);
  put_u16(out, 4U, latency);
  put_u16(out, 6U, message.frame_counter);
  return R::success(rms.saturated || latency_saturated ? Saturation::kSaturated : Saturation::kNone);
}

Status<CanError> encode_heartbeat(std::uint8_t node_id, NmtState state, Frame& out) noexcept {
  if (!valid_node_id(node_id)) {
    return Status<CanError>::failure(CanError::kInvalidArgument);
  }
  start_frame(out, heartbeat_id(node_id), kHeartbeatLength);
  out.data[0] = static_cast<std::uint8_t>(state);
  return ok_status<CanError>();
}

Status<CanError> encode_emcy(std::uint8_t node_id, const EmcyMessage& message, Frame& out) noexcept {
  if (!valid_node_id(node_id)) {
    return Status<CanError>::failure(CanError::kInvalidArgument);
  }
  start_frame(out, emcy_id(node_id), kEmcyLength);
  put_u16(out, 0U, message.error_code);
  out.data[2] = message.error_register;
  out.data[3] = message.fault_id;
  put_u16(out, 4U, static_cast<std::uint16_t>(message.detail & 0xFFFFU));
  put_u16(out, 6U, static_cast<std::uint16_t>(message.detail >> 16U));
  return ok_status<CanError>();
}

Status<CanError> encode_nmt(const NmtMessage& message, Frame& out) noexcept {
  if (message.node_id > kMaxNodeId) {
    return Status<CanError>::failure(CanError::kInvalidArgument);
  }
  start_frame(out, kNmtId, kNmtLength);
  out.data[0] = static_cast<std::uint8_t>(message.command);
  out.data[1] = message.node_id;
  return ok_status<CanError>();
}

Status<CanError> encode_sync(Frame& out) noexcept {
  start_frame(out, kSyncId, 0U);
  return ok_status<CanError>();
}

Result<TcpMessage, CanError> decode_tcp(std::uint8_t node_id, const Frame& frame) noexcept {
  using R = Result<TcpMessage, CanError>;
  const auto three = decode_three(tcp_id(node_id), frame, kLengthLsbMm, kLengthLsbMm, kLengthLsbMm);
  if (!three) {
    return R::failure(three.error());
  }
  TcpMessage out;
  out.x_mm = three.value().a;
  out.y_mm = three.value().b;
  out.z_mm = three.value().c;
  out.status = three.value().status;
  out.counter = three.value().counter;
  return R::success(out);
}

namespace {
Result<JointsMessage, CanError> decode_joint_like(std::uint32_t id, const Frame& frame) noexcept {
  using R = Result<JointsMessage, CanError>;
  const auto three = decode_three(id, frame, kLengthLsbMm, kAngleLsbRad, kAngleLsbRad);
  if (!three) {
    return R::failure(three.error());
  }
  JointsMessage out;
  out.lambda_mm = three.value().a;
  out.phi_rad = three.value().b;
  out.theta_rad = three.value().c;
  out.status = three.value().status;
  out.counter = three.value().counter;
  return R::success(out);
}
}  // namespace

Result<JointsMessage, CanError> decode_joints(std::uint8_t node_id, const Frame& frame) noexcept {
  return decode_joint_like(joints_id(node_id), frame);
}

Result<EncoderPriorMessage, CanError> decode_encoder_prior(std::uint8_t node_id, const Frame& frame) noexcept {
  return decode_joint_like(encoder_prior_id(node_id), frame);
}

Result<MechanicalMessage, CanError> decode_mechanical(std::uint8_t node_id, const Frame& frame) noexcept {
  using R = Result<MechanicalMessage, CanError>;
  CanError error = CanError::kInvalidArgument;
  if (!check_id_length(frame, mechanical_id(node_id), kPdoLength, error)) {
    return R::failure(error);
  }
  MechanicalMessage out;
  out.x_ch_mm = get_i16(frame, 0U) * kLengthLsbMm;
  out.y_ch_mm = get_i16(frame, 2U) * kLengthLsbMm;
  out.psi_rad = get_i16(frame, 4U) * kAngleLsbRad;
  out.mu_rad = get_i16(frame, 6U) * kAngleLsbRad;
  return R::success(out);
}

Result<QualityMessage, CanError> decode_quality(std::uint8_t node_id, const Frame& frame) noexcept {
  using R = Result<QualityMessage, CanError>;
  CanError error = CanError::kInvalidArgument;
  if (!check_id_length(frame, quality_id(node_id), kPdoLength, error)) {
    return R::failure(error);
  }
  QualityMessage out;
  out.corners_detected = frame.data[0];
  out.corners_used = frame.data[1];
  out.rms_px = get_u16(frame, 2U) * kRmsLsbPx;
  out.latency_us = get_u16(frame, 4U);
  out.frame_counter = get_u16(frame, 6U);
  return R::success(out);
}

Result<NmtState, CanError> decode_heartbeat(std::uint8_t node_id, const Frame& frame) noexcept {
  using R = Result<NmtState, CanError>;
  CanError error = CanError::kInvalidArgument;
  if (!check_id_length(frame, heartbeat_id(node_id), kHeartbeatLength, error)) {
    return R::failure(error);
  }
  const std::uint8_t state = frame.data[0];
  switch (state) {
    case static_cast<std::uint8_t>(NmtState::kBootUp):
    case static_cast<std::uint8_t>(NmtState::kStopped):
    case static_cast<std::uint8_t>(NmtState::kOperational):
    case static_cast<std::uint8_t>(NmtState::kPreOperational):
      return R::success(static_cast<NmtState>(state));
    default:
      return R::failure(CanError::kInvalidArgument);
  }
}

Result<EmcyMessage, CanError> decode_emcy(std::uint8_t node_id, const Frame& frame) noexcept {
  using R = Result<EmcyMessage, CanError>;
  CanError error = CanError::kInvalidArgument;
  if (!check_id_length(frame, emcy_id(node_id), kEmcyLength, error)) {
    return R::failure(error);
  }
  EmcyMessage out;
  out.error_code = get_u16(frame, 0U);
  out.error_register = frame.data[2];
  out.fault_id = frame.data[3];
  out.detail = static_cast<std::uint32_t>(get_u16(frame, 4U)) | (static_cast<std::uint32_t>(get_u16(frame, 6U)) << 16U);
  return R::success(out);
}

Result<NmtMessage, CanError> decode_nmt(const Frame& frame) noexcept {
  using R = Result<NmtMessage, CanError>;
  CanError error = CanError::kInvalidArgument;
  if (!check_id_length(frame, kNmtId, kNmtLength, error)) {
    return R::failure(error);
  }
  NmtMessage out;
  switch (frame.data[0]) {
    case static_cast<std::uint8_t>(NmtCommand::kStart):
    case static_cast<std::uint8_t>(NmtCommand::kStop):
    case static_cast<std::uint8_t>(NmtCommand::kEnterPreOperational):
    case static_cast<std::uint8_t>(NmtCommand::kResetNode):
    case static_cast<std::uint8_t>(NmtCommand::kResetCommunication):
      out.command = static_cast<NmtCommand>(frame.data[0]);
      break;
    default:
      return R::failure(CanError::kUnknownCommand);
  }
  out.node_id = frame.data[1];
  return R::success(out);
}

Status<CanError> decode_sync(const Frame& frame) noexcept {
  if (frame.id != kSyncId) {
    return Status<CanError>::failure(CanError::kWrongId);
  }
  if (frame.length > 1U) {
    return Status<CanError>::failure(CanError::kWrongLength);
  }
  return ok_status<CanError>();
}

}  // namespace can
}  // namespace tcpest
