#include "tcpest/can_iface/node.hpp"

#include <cmath>

namespace tcpest {
namespace can {
namespace {

std::uint32_t fault_bit(Fault fault) noexcept { return 1U << (static_cast<std::uint8_t>(fault) - 1U); }

bool is_estimate(EstimateStatus status) noexcept {
  return status == EstimateStatus::kValid || status == EstimateStatus::kDegraded;
}

}  // namespace

Status<CanError> validate(const NodeConfig& config) noexcept {
  if (!valid_node_id(config.node_id) || config.heartbeat_period_us < 0) {
    return Status<CanError>::failure(CanError::kInvalidArgument);
  }
  return validate(config.prior_e2e);
}

Node::Node() noexcept { reset_application(); }

Status<CanError> Node::configure(const NodeConfig& config) noexcept {
  const Status<CanError> valid = validate(config);
  if (!valid) {
    return valid;
  }
  config_ = config;
  prior_rx_ = E2eReceiver(config.prior_e2e);
  reset_application();
  return ok_status<CanError>();
}

// Reset communication (CiA 301): counters, sequence references and the
// heartbeat schedule restart, and the node boots up again.
void Node::reset_communication() noexcept {
  tcp_counter_.reset();
  joints_counter_.reset();
  prior_rx_.reset();
  have_prior_ = false;
  prior_ = EncoderPrior{};
  pdos_pending_ = false;
  rx_lost_this_cycle_ = 0U;
  heartbeat_scheduled_ = false;
  state_ = NmtState::kBootUp;
  boot_pending_ = true;
}

// Reset node: the application's state too (estimates, faults).
void Node::reset_application() noexcept {
  latest_ = Estimate{};
  last_fresh_ = Estimate{};
  have_fresh_ = false;
  active_faults_ = 0U;
  pending_raise_ = 0U;
  pending_clear_ = 0U;
  for (std::uint32_t& detail : fault_detail_) {
    detail = 0U;
  }
  reset_communication();
}

RxSummary Node::receive(const Frame* frames, std::size_t count, std::int64_t now_us) noexcept {
  RxSummary summary;
  if (frames == nullptr) {
    return summary;
  }
  const std::size_t handled = count < kMaxRxPerCycle ? count : kMaxRxPerCycle;
  if (count > handled) {
    summary.dropped = static_cast<std::uint32_t>(count - handled);
    counters_.rx_dropped_over_budget += summary.dropped;
  }
  for (std::size_t i = 0U; i < handled; ++i) {
    const Frame& frame = frames[i];
    ++summary.processed;
    ++counters_.rx_frames;
    if (frame.id == kNmtId) {
      handle_nmt(frame, summary);
    } else if (state_ == NmtState::kBootUp) {
      // Initialisation: only NMT is looked at (and ignored too, below).
      ++counters_.rx_ignored_in_state;
      ++summary.ignored;
    } else if (frame.id == kSyncId) {
      if (!decode_sync(frame)) {
        ++counters_.sync_wrong_length;
        ++summary.ignored;
      } else if (state_ != NmtState::kOperational) {
        ++counters_.rx_ignored_in_state;
        ++summary.ignored;
      } else {
        ++counters_.sync_received;
        ++summary.syncs;
        if (config_.sync_mode) {
          if (pdos_pending_) {
            ++counters_.sync_coalesced;
          }
          pdos_pending_ = true;
        }
      }
    } else if (frame.id == encoder_prior_id(config_.node_id)) {
      handle_prior(frame, now_us, summary);
    } else {
      ++counters_.rx_unknown_id;
      ++summary.ignored;
    }
  }
  rx_lost_this_cycle_ += summary.dropped;
  return summary;
}

void Node::handle_nmt(const Frame& frame, RxSummary& summary) noexcept {
  const Result<NmtMessage, CanError> nmt = decode_nmt(frame);
  if (!nmt) {
    if (nmt.error() == CanError::kUnknownCommand) {
      ++counters_.nmt_unknown_command;
    } else {
      ++counters_.nmt_wrong_length;
    }
    ++summary.ignored;
    return;
  }
  if (nmt.value().node_id != 0U && nmt.value().node_id != config_.node_id) {
    ++counters_.nmt_other_node;
    ++summary.ignored;
    return;
  }
  if (state_ == NmtState::kBootUp) {
    ++counters_.rx_ignored_in_state;
    ++summary.ignored;
    return;
  }
  switch (nmt.value().command) {
    case NmtCommand::kStart: state_ = NmtState::kOperational; break;
    case NmtCommand::kStop:
      state_ = NmtState::kStopped;
      pdos_pending_ = false;
      break;
    case NmtCommand::kEnterPreOperational:
      state_ = NmtState::kPreOperational;
      pdos_pending_ = false;
      break;
    case NmtCommand::kResetNode: reset_application(); break;
    case NmtCommand::kResetCommunication: reset_communication(); break;
  }
  ++counters_.nmt_applied;
  summary.nmt_changed = true;
}

void Node::handle_prior(const Frame& frame, std::int64_t now_us, RxSummary& summary) noexcept {
  if (state_ != NmtState::kOperational) {
    ++counters_.rx_ignored_in_state;
    ++summary.ignored;
    return;
  }
  const Result<EncoderPriorMessage, CanError> decoded = decode_encoder_prior(config_.node_id, frame);
  if (!decoded) {
    prior_rx_.count_decode_error(decoded.error());
    if (decoded.error() == CanError::kWrongLength) {
      ++counters_.prior_wrong_length;
    }
    static_cast<void>(apply_fault(Fault::kPriorE2eError, true, static_cast<std::uint32_t>(decoded.error())));  // valid id
    ++summary.ignored;
    return;
  }
  const Status<CanError> sequence = prior_rx_.check_counter(decoded.value().counter, now_us);
  if (!sequence) {
    static_cast<void>(apply_fault(Fault::kPriorE2eError, true, static_cast<std::uint32_t>(sequence.error())));  // valid id
    ++summary.ignored;
    return;
  }
  static_cast<void>(apply_fault(Fault::kPriorE2eError, false, 0U));  // valid fault id
  if (decoded.value().status == EstimateStatus::kInvalid) {
    ++counters_.prior_invalid_status;
    ++summary.ignored;
    return;
  }
  prior_.lambda_mm = decoded.value().lambda_mm;
  prior_.phi_rad = decoded.value().phi_rad;
  prior_.theta_rad = decoded.value().theta_rad;
  prior_.status = decoded.value().status;
  prior_.received_us = now_us;
  have_prior_ = true;
  summary.prior_updated = true;
}

Result<EncoderPrior, CanError> Node::encoder_prior(std::int64_t now_us) noexcept {
  using R = Result<EncoderPrior, CanError>;
  if (!have_prior_) {
    return R::failure(CanError::kNoData);
  }
  if (now_us - prior_.received_us > config_.prior_e2e.timeout_us) {
    static_cast<void>(prior_rx_.freshness(now_us));  // called for its count of timeouts; the verdict is kStale anyway
    return R::failure(CanError::kStale);
  }
  return R::success(prior_);
}

Status<CanError> Node::publish(const Estimate& estimate) noexcept {
  if (static_cast<std::uint8_t>(estimate.status) > static_cast<std::uint8_t>(EstimateStatus::kInvalid)) {
    return Status<CanError>::failure(CanError::kInvalidArgument);
  }
  latest_ = estimate;
  if (is_estimate(estimate.status)) {
    last_fresh_ = estimate;
    have_fresh_ = true;
  } else if (estimate.status == EstimateStatus::kHeld) {
    // Repeat the last pose; without one there is nothing to hold.
    if (have_fresh_) {
      latest_.tcp_x_mm = last_fresh_.tcp_x_mm;
      latest_.tcp_y_mm = last_fresh_.tcp_y_mm;
      latest_.tcp_z_mm = last_fresh_.tcp_z_mm;
      latest_.lambda_mm = last_fresh_.lambda_mm;
      latest_.phi_rad = last_fresh_.phi_rad;
      latest_.theta_rad = last_fresh_.theta_rad;
      latest_.x_ch_mm = last_fresh_.x_ch_mm;
      latest_.y_ch_mm = last_fresh_.y_ch_mm;
      latest_.psi_rad = last_fresh_.psi_rad;
      latest_.mu_rad = last_fresh_.mu_rad;
    } else {
      latest_.status = EstimateStatus::kInvalid;
    }
  }
  if (!config_.sync_mode) {
    pdos_pending_ = true;
  }
  return ok_status<CanError>();
}

bool node_owned(Fault fault) noexcept {
  return fault == Fault::kPriorTimeout || fault == Fault::kPriorE2eError || fault == Fault::kCanRxOverrun;
}

Status<CanError> Node::set_fault(Fault fault, bool active, std::uint32_t detail) noexcept {
  if (fault_info(fault) == nullptr) {
    return Status<CanError>::failure(CanError::kInvalidArgument);
  }
  if (node_owned(fault)) {
    return Status<CanError>::failure(CanError::kNotAllowed);
  }
  return apply_fault(fault, active, detail);
}

Status<CanError> Node::apply_fault(Fault fault, bool active, std::uint32_t detail) noexcept {
  if (fault_info(fault) == nullptr) {
    return Status<CanError>::failure(CanError::kInvalidArgument);
  }
  const std::uint32_t bit = fault_bit(fault);
  const bool was_active = (active_faults_ & bit) != 0U;
  if (active == was_active) {
    return ok_status<CanError>();
  }
  if (state_ == NmtState::kStopped) {
    // CiA 301: no EMCY in stopped; the state is still tracked.
    ++counters_.emcy_suppressed;
  } else if (active) {
    pending_raise_ |= bit;
  } else {
    pending_clear_ |= bit;
  }
  if (active) {
    active_faults_ |= bit;
    fault_detail_[static_cast<std::uint8_t>(fault) - 1U] = detail;
  } else {
    active_faults_ &= ~bit;
  }
  return ok_status<CanError>();
}

bool Node::fault_active(Fault fault) const noexcept {
  return fault_info(fault) != nullptr && (active_faults_ & fault_bit(fault)) != 0U;
}

std::uint8_t Node::error_register() const noexcept {
  std::uint8_t bits = 0U;
  for (std::uint8_t id = 1U; id <= kFaultCount; ++id) {
    if ((active_faults_ & (1U << (id - 1U))) != 0U) {
      bits = static_cast<std::uint8_t>(bits | fault_info(static_cast<Fault>(id))->register_bits);
    }
  }
  return bits;
}

bool Node::push(TxBatch& out, const Frame& frame) noexcept {
  if (!out.push_back(frame)) {
    ++counters_.tx_batch_full;
    return false;
  }
  return true;
}

bool Node::emit_emcy_edge(TxBatch& out, std::uint8_t id, bool raise) noexcept {
  const std::uint32_t bit = 1U << (id - 1U);
  std::uint32_t& pending = raise ? pending_raise_ : pending_clear_;
  if ((pending & bit) == 0U) {
    return true;
  }
  const FaultInfo* info = fault_info(static_cast<Fault>(id));
  EmcyMessage message;
  message.fault_id = id;
  if (raise) {
    message.error_code = info->error_code;
    // The register with this fault in it, even if it has already cleared again.
    message.error_register = static_cast<std::uint8_t>(error_register() | info->register_bits);
    message.detail = fault_detail_[id - 1U];
  } else {
    message.error_code = 0x0000U;  // CiA 301 "error reset or no error"
    message.error_register = error_register();
  }
  Frame frame;
  if (!encode_emcy(config_.node_id, message, frame) || !push(out, frame)) {
    return false;
  }
  pending &= ~bit;
  ++counters_.emcy_sent;
  return true;
}

bool Node::emit_emcy(TxBatch& out) noexcept {
  for (std::uint8_t id = 1U; id <= kFaultCount; ++id) {
    // Both edges since the last collect: the one that leaves the fault in
    // its current state goes last, so the receiver ends in the right state.
    const bool active = (active_faults_ & (1U << (id - 1U))) != 0U;
    if (!emit_emcy_edge(out, id, !active) || !emit_emcy_edge(out, id, active)) {
      return false;
    }
  }
  return true;
}

bool Node::emit_pdos(TxBatch& out) noexcept {
  if (out.size() + 4U > TxBatch::capacity()) {
    ++counters_.tx_batch_full;
    return false;
  }
  const Estimate& e = latest_;
  bool saturated = false;
  Frame frame;

  TcpMessage tcp;
  tcp.x_mm = e.tcp_x_mm;
  tcp.y_mm = e.tcp_y_mm;
  tcp.z_mm = e.tcp_z_mm;
  tcp.status = e.status;
  tcp.counter = tcp_counter_.take();
  const auto tcp_result = encode_tcp(config_.node_id, tcp, frame);
  if (!tcp_result) {
    return false;
  }
  saturated = saturated || tcp_result.value() == Saturation::kSaturated;
  static_cast<void>(push(out, frame));  // room checked above

  JointsMessage joints;
  joints.lambda_mm = e.lambda_mm;
  joints.phi_rad = e.phi_rad;
  joints.theta_rad = e.theta_rad;
  joints.status = e.status;
  joints.counter = joints_counter_.take();
  const auto joints_result = encode_joints(config_.node_id, joints, frame);
  if (!joints_result) {
    return false;
  }
  saturated = saturated || joints_result.value() == Saturation::kSaturated;
  static_cast<void>(push(out, frame));  // room checked above

  MechanicalMessage mechanical;
  mechanical.x_ch_mm = e.x_ch_mm;
  mechanical.y_ch_mm = e.y_ch_mm;
  mechanical.psi_rad = e.psi_rad;
  mechanical.mu_rad = e.mu_rad;
  const auto mechanical_result = encode_mechanical(config_.node_id, mechanical, frame);
  if (!mechanical_result) {
    return false;
  }
  saturated = saturated || mechanical_result.value() == Saturation::kSaturated;
  static_cast<void>(push(out, frame));  // room checked above

  QualityMessage quality;
  quality.corners_detected = e.corners_detected;
  quality.corners_used = e.corners_used;
  quality.rms_px = e.rms_px;
  quality.latency_us = e.latency_us;
  quality.frame_counter = e.frame_counter;
  const auto quality_result = encode_quality(config_.node_id, quality, frame);
  if (!quality_result) {
    return false;
  }
  static_cast<void>(push(out, frame));  // room checked above

  if (saturated) {
    ++counters_.pdo_saturated;
  }
  ++counters_.pdo_cycles_sent;
  return true;
}

void Node::update_prior_timeout(std::int64_t now_us) noexcept {
  if (!config_.prior_expected || state_ != NmtState::kOperational) {
    return;
  }
  const Status<CanError> fresh = prior_rx_.freshness(now_us);
  bool missing = false;
  if (!fresh) {
    missing = fresh.error() == CanError::kStale || now_us - boot_us_ > config_.prior_e2e.timeout_us;
  }
  static_cast<void>(apply_fault(Fault::kPriorTimeout, missing, 0U));  // valid fault id
}

Status<CanError> Node::report_rx_lost(std::uint32_t frames) noexcept {
  rx_lost_this_cycle_ += frames;
  return ok_status<CanError>();
}

Status<CanError> Node::collect(std::int64_t now_us, TxBatch& out) noexcept {
  const auto full = Status<CanError>::failure(CanError::kFull);
  // A cycle that lost received frames is an overrun; the next clean one clears it.
  static_cast<void>(apply_fault(Fault::kCanRxOverrun, rx_lost_this_cycle_ > 0U, rx_lost_this_cycle_));  // valid id
  rx_lost_this_cycle_ = 0U;
  if (boot_pending_) {
    Frame boot;
    if (!encode_heartbeat(config_.node_id, NmtState::kBootUp, boot) || !push(out, boot)) {
      return full;
    }
    ++counters_.boot_ups_sent;
    boot_pending_ = false;
    boot_us_ = now_us;
    state_ = config_.start_operational ? NmtState::kOperational : NmtState::kPreOperational;
    heartbeat_scheduled_ = true;
    next_heartbeat_us_ = now_us + config_.heartbeat_period_us;
  }
  update_prior_timeout(now_us);
  if (state_ == NmtState::kStopped) {
    pending_raise_ = 0U;
    pending_clear_ = 0U;
  } else if (!emit_emcy(out)) {
    return full;
  }
  if (pdos_pending_ && state_ == NmtState::kOperational) {
    if (!emit_pdos(out)) {
      return full;
    }
  }
  pdos_pending_ = false;
  if (config_.heartbeat_period_us > 0 && heartbeat_scheduled_ && now_us >= next_heartbeat_us_) {
    Frame heartbeat;
    if (!encode_heartbeat(config_.node_id, state_, heartbeat) || !push(out, heartbeat)) {
      return full;
    }
    ++counters_.heartbeats_sent;
    next_heartbeat_us_ += config_.heartbeat_period_us;
    if (next_heartbeat_us_ <= now_us) {
      // More than a period late (a stalled loop): restart the grid, no burst.
      next_heartbeat_us_ = now_us + config_.heartbeat_period_us;
    }
  }
  return ok_status<CanError>();
}

}  // namespace can
}  // namespace tcpest
