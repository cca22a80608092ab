#include "tcpest/can_iface/receiver.hpp"

namespace tcpest {
namespace can {

Status<CanError> validate(const ReceiverConfig& config) noexcept {
  if (!valid_node_id(config.node_id)) {
    return Status<CanError>::failure(CanError::kInvalidArgument);
  }
  return validate(config.e2e);
}

const char* to_string(Message message) noexcept {
  switch (message) {
    case Message::kTcp: return "tcp";
    case Message::kJoints: return "joints";
    case Message::kMechanical: return "mechanical";
    case Message::kQuality: return "quality";
    case Message::kHeartbeat: return "heartbeat";
    case Message::kEmcy: return "emcy";
  }
  return "unknown";
}

Result<Message, CanError> message_of(std::uint8_t node_id, std::uint32_t cob_id) noexcept {
  using R = Result<Message, CanError>;
  if (!valid_node_id(node_id)) {
    return R::failure(CanError::kInvalidArgument);
  }
  if (cob_id == tcp_id(node_id)) {
    return R::success(Message::kTcp);
  }
  if (cob_id == joints_id(node_id)) {
    return R::success(Message::kJoints);
  }
  if (cob_id == mechanical_id(node_id)) {
    return R::success(Message::kMechanical);
  }
  if (cob_id == quality_id(node_id)) {
    return R::success(Message::kQuality);
  }
  if (cob_id == heartbeat_id(node_id)) {
    return R::success(Message::kHeartbeat);
  }
  if (cob_id == emcy_id(node_id)) {
    return R::success(Message::kEmcy);
  }
  return R::failure(CanError::kUnknownId);
}

Receiver::Receiver(const ReceiverConfig& config) noexcept {
  static_cast<void>(configure(config));  // an invalid configuration keeps the defaults; configure() says why
}

Status<CanError> Receiver::configure(const ReceiverConfig& config) noexcept {
  const Status<CanError> valid = validate(config);
  if (!valid) {
    return valid;
  }
  config_ = config;
  tcp_rx_ = E2eReceiver(config.e2e);
  joints_rx_ = E2eReceiver(config.e2e);
  tcp_timeouts_seen_ = 0U;
  have_tcp_ = false;
  have_joints_ = false;
  have_mechanical_ = false;
  have_quality_ = false;
  have_nmt_ = false;
  have_emcy_ = false;
  return ok_status<CanError>();
}

void Receiver::update(std::int64_t now_us) noexcept {
  static_cast<void>(tcp_rx_.freshness(now_us));  // called for its count of timeouts, read below
  const std::uint32_t timeouts = tcp_rx_.counters().timeouts;
  counters_.stale_events += timeouts - tcp_timeouts_seen_;
  tcp_timeouts_seen_ = timeouts;
}

Result<Message, CanError> Receiver::receive(const Frame& frame, std::int64_t now_us) noexcept {
  using R = Result<Message, CanError>;
  ++counters_.frames;
  update(now_us);
  const R message = message_of(config_.node_id, frame.id);
  if (!message) {
    ++counters_.other_id;
    return message;
  }
  if (message.value() == Message::kTcp || message.value() == Message::kJoints) {
    return receive_e2e(message.value(), frame, now_us);
  }
  return receive_plain(message.value(), frame, now_us);
}

Result<Message, CanError> Receiver::refuse_e2e(E2eReceiver& stream, CanError error) noexcept {
  if (error == CanError::kCounterJump) {
    ++counters_.counter_jumps;
  } else {
    ++counters_.e2e_failures;
  }
  if (error == CanError::kBadCrc || error == CanError::kWrongLength || error == CanError::kBadCounter) {
    stream.count_decode_error(error);  // check_counter() counts the sequence errors itself
  }
  return Result<Message, CanError>::failure(error);
}

Result<Message, CanError> Receiver::receive_e2e(Message message, const Frame& frame, std::int64_t now_us) noexcept {
  using R = Result<Message, CanError>;
  const bool is_tcp = message == Message::kTcp;
  E2eReceiver& stream = is_tcp ? tcp_rx_ : joints_rx_;
  std::uint8_t counter = 0U;
  TcpMessage tcp;
  JointsMessage joints;
  if (is_tcp) {
    const Result<TcpMessage, CanError> decoded = decode_tcp(config_.node_id, frame);
    if (!decoded) {
      return refuse_e2e(stream, decoded.error());
    }
    tcp = decoded.value();
    counter = tcp.counter;
  } else {
    const Result<JointsMessage, CanError> decoded = decode_joints(config_.node_id, frame);
    if (!decoded) {
      return refuse_e2e(stream, decoded.error());
    }
    joints = decoded.value();
    counter = joints.counter;
  }
  const Status<CanError> sequence = stream.check_counter(counter, now_us);
  if (!sequence) {
    return refuse_e2e(stream, sequence.error());
  }
  if (is_tcp) {
    tcp_ = Received<TcpMessage>{tcp, now_us};
    have_tcp_ = true;
  } else {
    joints_ = Received<JointsMessage>{joints, now_us};
    have_joints_ = true;
  }
  ++counters_.decoded;
  return R::success(message);
}

Result<Message, CanError> Receiver::receive_plain(Message message, const Frame& frame, std::int64_t now_us) noexcept {
  using R = Result<Message, CanError>;
  CanError error = CanError::kInvalidArgument;
  bool ok = false;
  switch (message) {
    case Message::kMechanical: {
      const auto decoded = decode_mechanical(config_.node_id, frame);
      ok = decoded.ok();
      if (ok) {
        mechanical_ = Received<MechanicalMessage>{decoded.value(), now_us};
        have_mechanical_ = true;
      } else {
        error = decoded.error();
      }
      break;
    }
    case Message::kQuality: {
      const auto decoded = decode_quality(config_.node_id, frame);
      ok = decoded.ok();
      if (ok) {
        quality_ = Received<QualityMessage>{decoded.value(), now_us};
        have_quality_ = true;
      } else {
        error = decoded.error();
      }
      break;
    }
    case Message::kHeartbeat: {
      const auto decoded = decode_heartbeat(config_.node_id, frame);
      ok = decoded.ok();
      if (ok) {
        nmt_ = Received<NmtState>{decoded.value(), now_us};
        have_nmt_ = true;
        if (decoded.value() == NmtState::kBootUp) {
          // A (re)started node restarts its alive counters: so do the streams.
          ++counters_.boot_ups;
          tcp_rx_.reset();
          joints_rx_.reset();
        }
      } else {
        error = decoded.error();
      }
      break;
    }
    case Message::kEmcy: {
      const auto decoded = decode_emcy(config_.node_id, frame);
      ok = decoded.ok();
      if (ok) {
        emcy_ = Received<EmcyMessage>{decoded.value(), now_us};
        have_emcy_ = true;
        if (decoded.value().error_code == 0U) {
          ++counters_.emcy_cleared;
        } else {
          ++counters_.emcy_raised;
        }
      } else {
        error = decoded.error();
      }
      break;
    }
    case Message::kTcp:
    case Message::kJoints: break;  // E2E messages: receive_e2e()
  }
  if (!ok) {
    ++counters_.malformed;
    return R::failure(error);
  }
  ++counters_.decoded;
  return R::success(message);
}

bool Receiver::stale(std::int64_t now_us) const noexcept {
  return !have_tcp_ || now_us - tcp_.received_us > config_.e2e.timeout_us;
}

EstimateStatus Receiver::estimate_status(std::int64_t now_us) const noexcept {
  if (stale(now_us)) {
    return EstimateStatus::kInvalid;
  }
  return tcp_.value.status;
}

namespace {
template <typename T>
Result<Received<T>, CanError> latest(bool have, const Received<T>& value) noexcept {
  if (!have) {
    return Result<Received<T>, CanError>::failure(CanError::kNoData);
  }
  return Result<Received<T>, CanError>::success(value);
}
}  // namespace

Result<Received<TcpMessage>, CanError> Receiver::tcp() const noexcept { return latest(have_tcp_, tcp_); }
Result<Received<JointsMessage>, CanError> Receiver::joints() const noexcept { return latest(have_joints_, joints_); }
Result<Received<MechanicalMessage>, CanError> Receiver::mechanical() const noexcept {
  return latest(have_mechanical_, mechanical_);
}
Result<Received<QualityMessage>, CanError> Receiver::quality() const noexcept {
  return latest(have_quality_, quality_);
}
Result<Received<NmtState>, CanError> Receiver::nmt_state() const noexcept { return latest(have_nmt_, nmt_); }
Result<Received<EmcyMessage>, CanError> Receiver::last_emcy() const noexcept { return latest(have_emcy_, emcy_); }

}  // namespace can
}  // namespace tcpest
